// Shared by the binding sources: argument conversion (paths, parameter sets, dicts <-> TOML
// tables) and the registration function of each part of the module.
#pragma once

#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <toml++/toml.h>

#include <granflow/io/parameter_set.hpp>

namespace granflow::python {

namespace py = pybind11;

// str or os.PathLike -> path string (TypeError otherwise).
std::string path_arg(py::handle h, const char* what);
// A parameter set argument: a ParameterSet, a name under data/params or a path, or a dict laid
// out like a parameter-set file (read by the same code; messages name "<dict>").
io::ParameterSet params_arg(py::handle h);
// "section.key=value" strings: None, one string, or a sequence of strings.
std::vector<std::string> strings_arg(py::handle h, const char* what);

// A dict (nested dicts, lists, bool, int, float, str, NumPy scalars and arrays) as a TOML table;
// `where` names the argument in type errors.
toml::table to_toml(const py::dict& d, const std::string& where);
// A TOML node as Python values (tables -> dict, arrays -> list).
py::object to_python(const toml::node& n);

// Equal-length columns as an insertion-ordered dict name -> 1-D float64 array.
py::dict columns_dict(const std::vector<std::string>& names, const std::vector<std::vector<double>>& columns);
py::array_t<double> to_array(const std::vector<double>& v);

void register_params(py::module_& m);
void register_update(py::module_& m);
void register_element(py::module_& m);
void register_calibrate(py::module_& m);
void register_mpm(py::module_& m);

}  // namespace granflow::python
