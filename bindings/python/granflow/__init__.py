"""granflow from Python: parameter sets, the constitutive update on arrays, element tests,
calibration jobs and MPM runs, through the same C++ code as the `granflow` program.
See docs/python.md."""
import os as _os

# Installed beside <prefix>/share/granflow/data: use that data unless GRANFLOW_DATA_DIR is set.
_share = _os.path.normpath(_os.path.join(_os.path.dirname(__file__), "..", "..", "..", "..",
                                         "share", "granflow", "data"))
if "GRANFLOW_DATA_DIR" not in _os.environ and _os.path.isdir(_share):
    _os.environ["GRANFLOW_DATA_DIR"] = _share

from ._granflow import (FLAGS, FLAG_ERROR_MASK, InputError, OutputError, ParameterSet, calibrate,
                        cuda_available, data_directory, element, element_columns, load_params, mpm,
                        parse_params, update)

__all__ = ["FLAGS", "FLAG_ERROR_MASK", "InputError", "OutputError", "ParameterSet", "calibrate",
           "cuda_available", "data_directory", "element", "element_columns", "load_params", "mpm",
           "parse_params", "update"]
