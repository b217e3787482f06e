"""granflow from Python: parameter sets, the constitutive update on arrays, element tests,
calibration jobs and MPM runs, through the same C++ code as the `granflow` program.
See docs/python.md."""
import os as _os

# Installed beside <prefix>/share/granflow/data: use that data unless GRANFLOW_DATA_DIR is set.
_share = _os.path.normpath(_os.path.join(_os.path.dirname(__file__), "..", "..", "..", "..",
                                         "share", "granflow", "data"))

def _build_tree_data():
    """The source tree's data/ of a module in a build tree (build/granflow_source_dir.txt, written
    at configure time), as the program finds it (io/share.hpp); None elsewhere."""
    d = _os.path.dirname(_os.path.abspath(__file__))
    for _ in range(5):
        f = _os.path.join(d, "granflow_source_dir.txt")
        if _os.path.isfile(f):
            with open(f) as fh:
                data = _os.path.join(fh.readline().strip(), "data")
            return data if _os.path.isdir(_os.path.join(data, "params")) else None
        d = _os.path.dirname(d)
    return None


# The program finds its data from its own folder; the module's program is python3, so the
# module says where: beside an install prefix, or the build tree's source.
if "GRANFLOW_DATA_DIR" not in _os.environ:
    _data = _share if _os.path.isdir(_share) else _build_tree_data()
    if _data:
        _os.environ["GRANFLOW_DATA_DIR"] = _data

from ._granflow import (FLAGS, FLAG_ERROR_MASK, InputError, OutputError, ParameterSet, calibrate,
                        cuda_available, data_directory, element, element_columns, load_params, mpm,
                        parse_params, update)

__all__ = ["FLAGS", "FLAG_ERROR_MASK", "InputError", "OutputError", "ParameterSet", "calibrate",
           "cuda_available", "data_directory", "element", "element_columns", "load_params", "mpm",
           "parse_params", "update"]
