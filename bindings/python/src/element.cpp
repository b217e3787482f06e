// granflow.element: element tests from a test file or a dict laid out like one, run by the
// element-test driver as `granflow element` runs them; columns as in the CSV.
#include <granflow/elementtest/run.hpp>

#include "common.hpp"
#include "test_file_text.hpp"  // read_test_file: a dict is read by the file's code

namespace granflow::python {

namespace {

py::dict stats_dict(const elementtest::RunStats& s) {
  py::dict d;
  d["steps"] = s.steps;
  d["rhs_evals"] = s.rhs_evals;
  d["events"] = s.events;
  d["newton_fails"] = s.newton_fails;
  d["cpu_seconds"] = s.cpu_seconds;
  d["tension_cutoff"] = s.tension_cutoff;
  d["cutoff_time"] = s.cutoff_time;
  d["vs_clamped"] = s.vs_clamped;
  return d;
}

py::object element(py::handle test, py::handle params, py::handle overrides, bool stats) {
  // As cmd_element.cpp: the file's set (or params), its overrides, then the caller's.
  elementtest::TestFile tf;
  std::string origin;
  if (py::isinstance<py::dict>(test)) {
    origin = "<dict>";
    tf = elementtest::read_test_file(to_toml(test.cast<py::dict>(), "test"), origin);
  } else {
    origin = path_arg(test, "test");
    tf = elementtest::load_test_file(origin);
  }
  io::ParameterSet set = params.is_none() ? io::load_parameter_set(tf.params) : params_arg(params);
  for (const auto& a : tf.overrides) io::apply_override(set, a, origin + ": overrides");
  for (const auto& a : strings_arg(overrides, "overrides")) io::apply_override(set, a);
  elementtest::ResultTable r;
  {
    py::gil_scoped_release nogil;
    r = elementtest::run_element_test(tf.test, set);
  }
  py::dict cols = columns_dict(r.names, r.columns);
  if (!stats) return std::move(cols);
  return py::make_tuple(cols, stats_dict(r.stats));
}

}  // namespace

void register_element(py::module_& m) {
  m.def("element", &element, py::arg("test"), py::arg("params") = py::none(), py::arg("overrides") = py::none(),
        py::arg("stats") = false,
        R"(Runs an element test as `granflow element TEST [--params P] [--set ...]` does.

test       a test file (data/tests/*.toml) or a dict laid out like one:
           {"params": "element_test", "overrides": [...], "test": {"path": ..., ...}}
params     parameter set instead of the file's (ParameterSet, name, path or dict)
overrides  "section.key=value" strings applied after the file's overrides (as --set)
stats      also return the run statistics (steps, rhs_evals, events, cpu_seconds, ...)

Returns a dict column -> 1-D float64 array with the CSV's columns in its order
(granflow.element_columns()), or (columns, stats) with stats=True.)");
  m.def("element_columns", &elementtest::result_column_names, "Column names of an element test (the CSV header)");
}

}  // namespace granflow::python
