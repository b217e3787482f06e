// The extension module granflow._granflow (imported by granflow/__init__.py). The project's
// exceptions become Python ones carrying the same messages:
//   io::InputError  -> granflow.InputError (a ValueError): bad files, keys, values, arguments
//   io::OutputError -> granflow.OutputError (an OSError): a file or folder could not be written
//   other std::runtime_error (solver failures, a run that stopped) -> RuntimeError
#include <granflow/io/input_error.hpp>
#include <granflow/io/output.hpp>

#include "common.hpp"

PYBIND11_MODULE(_granflow, m) {
  namespace gp = granflow::python;
  m.doc() = "granflow: the constitutive update, element tests, calibration and MPM runs (docs/python.md)";
  gp::py::register_exception<granflow::io::InputError>(m, "InputError", PyExc_ValueError);
  gp::py::register_exception<granflow::io::OutputError>(m, "OutputError", PyExc_OSError);
  gp::register_params(m);
  gp::register_update(m);
  gp::register_element(m);
  gp::register_calibrate(m);
  gp::register_mpm(m);
}
