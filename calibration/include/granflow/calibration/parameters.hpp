// Free parameters addressed by "section.key" (the keys of a parameter-set file).
#pragma once

#include <string>
#include <vector>

#include <granflow/io/parameter_set.hpp>

namespace granflow::calibration {

// Keys a calibration can free: every model parameter of a parameter-set file.
const std::vector<std::string>& settable_keys();

// Value of a key as written in the parameter file (phi_c_deg in degrees, e_sd = 1/V_sd - 1).
double get_parameter(const io::ParameterSet& set, const std::string& key);
// Sets a key without validation (the optimiser stays inside the validated bounds).
void set_parameter(io::ParameterSet& set, const std::string& key, double value);
// True when the key names a known parameter whose section the set has; else fills `why`.
bool parameter_addressable(const io::ParameterSet& set, const std::string& key, std::string& why);

}  // namespace granflow::calibration
