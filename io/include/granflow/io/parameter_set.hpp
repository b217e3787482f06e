// Parameter-set files (data/params/*.toml): the frictional and/or collisional parameters of
// MODEL.md 7, optional initial state, optional numerics. Loaded with full validation.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <granflow/constitutive.hpp>

namespace granflow::io {

class TomlTable;

struct ParameterSet {
  std::string name;
  std::string source;  // provenance
  std::optional<FrictionalParams<double>> frictional;
  std::optional<CollisionalParams<double>> collisional;
  std::vector<double> e0;  // initial void ratios named by the set (may be empty)
  std::optional<double> T0;
  std::string file;        // where it was loaded from
  // Initial void ratios of named experiments set by a calibration (a per-test free e0); not
  // part of the file format.
  std::map<std::string, double> test_e0;

  bool has_frictional() const { return frictional.has_value(); }
  bool has_collisional() const { return collisional.has_value(); }
  PhaseTransitionParams<double> phase_transition() const;  // throws unless both parts are present
};

// Reads a parameter set. `name_or_path` is a file path or the name of a set under data/params
// (e.g. "element_test"). Every value is validated; errors name file, line and key.
ParameterSet load_parameter_set(const std::string& name_or_path);
ParameterSet parse_parameter_set(TomlTable& root);
// Parses the text of a parameter-set file; `name` stands for the file in messages (fuzzing, tests).
ParameterSet parse_parameter_set_text(const std::string& text, const std::string& name);

// Applies "section.key=value" overrides (e.g. "frictional.phi_c_deg=31") with the same checks.
// `origin` says where the assignment came from in messages ("--set", "test.toml: overrides").
void apply_override(ParameterSet& set, const std::string& assignment, const std::string& origin = "--set");

// Writes a set in the format load_parameter_set reads (used by calibration).
std::string format_parameter_set(const ParameterSet& set);

// Cross-checks of an initial state against a set: e0 in (0, 2.97), V_s0 below V_sd.
void check_initial_void_ratio(const ParameterSet& set, double e0, const std::string& what);

// The data folder of the shipped files: $GRANFLOW_DATA_DIR, else share_directory()/data (share.hpp).
std::string data_directory();

}  // namespace granflow::io
