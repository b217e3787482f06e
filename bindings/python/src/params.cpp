// Parameter sets: io::ParameterSet as granflow.ParameterSet, loaded and overridden by the
// functions the CLI uses (same validation, same messages).
#include <sstream>

#include "common.hpp"
#include <granflow/io/toml_reader.hpp>

namespace granflow::python {

void register_params(py::module_& m) {
  py::class_<io::ParameterSet>(m, "ParameterSet",
                               "A parameter set (data/params/*.toml): load with granflow.load_params.")
      .def_readonly("name", &io::ParameterSet::name)
      .def_readonly("source", &io::ParameterSet::source)
      .def_readonly("file", &io::ParameterSet::file, "where it was loaded from ('<dict>' for a dict)")
      .def_readonly("e0", &io::ParameterSet::e0, "initial void ratios named by the set")
      .def_readonly("T0", &io::ParameterSet::T0)
      .def_property_readonly("has_frictional", &io::ParameterSet::has_frictional)
      .def_property_readonly("has_collisional", &io::ParameterSet::has_collisional)
      .def("to_toml", &io::format_parameter_set, "The set as a parameter-set file (what calibrate writes)")
      .def(
          "to_dict",
          [](const io::ParameterSet& s) {
            return to_python(io::TomlTable::parse_text(io::format_parameter_set(s), s.file));
          },
          "The set as a dict laid out like its file (load_params takes it back)")
      .def(
          "with_overrides",
          [](const io::ParameterSet& s, py::handle overrides) {
            io::ParameterSet out = s;
            for (const auto& a : strings_arg(overrides, "overrides")) io::apply_override(out, a);
            return out;
          },
          py::arg("overrides"), "A copy with \"section.key=value\" overrides applied (as --set)")
      .def("__repr__", [](const io::ParameterSet& s) {
        std::ostringstream os;
        os << "<granflow.ParameterSet '" << s.name << "' from " << s.file << ":"
           << (s.has_frictional() ? " frictional" : "") << (s.has_collisional() ? " collisional" : "") << ">";
        return os.str();
      });

  m.def(
      "load_params",
      [](py::handle what, py::handle overrides) {
        io::ParameterSet s = params_arg(what);
        for (const auto& a : strings_arg(overrides, "overrides")) io::apply_override(s, a);
        return s;
      },
      py::arg("params"), py::arg("overrides") = py::none(),
      "Loads a parameter set: a name under data/params (\"element_test\"), a TOML path, or a dict laid out "
      "like the file; overrides are \"section.key=value\" strings applied in order (as --set). Errors raise "
      "granflow.InputError with the CLI's message (file, line, key).");
  m.def(
      "parse_params", [](const std::string& text, const std::string& name) { return io::parse_parameter_set_text(text, name); },
      py::arg("text"), py::arg("name") = "<text>", "A parameter set from the text of a file; `name` stands for the file in messages");
  m.def("data_directory", &io::data_directory, "The folder of the shipped data (GRANFLOW_DATA_DIR or the source tree's data/)");
}

}  // namespace granflow::python
