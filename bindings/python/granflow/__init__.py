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

import functools as _functools

from . import _granflow
from ._granflow import FLAGS, FLAG_ERROR_MASK, InputError, OutputError, ParameterSet, cuda_available, data_directory


class InputTypeError(InputError, TypeError):
    """An argument of the wrong type: an InputError (so `except granflow.InputError` catches
    every bad argument) and a TypeError, as Python code expects."""


def _typed(f):
    """f, raising InputTypeError where it (or pybind11's argument matching) raises TypeError."""
    @_functools.wraps(f)
    def call(*args, **kwargs):
        try:
            return f(*args, **kwargs)
        except TypeError as e:
            if isinstance(e, InputError):
                raise
            raise InputTypeError(str(e)) from None
    return call


calibrate, element, element_columns, load_params, mpm, parse_params, update = (
    _typed(getattr(_granflow, n))
    for n in ("calibrate", "element", "element_columns", "load_params", "mpm", "parse_params", "update"))
ParameterSet.with_overrides = _typed(ParameterSet.with_overrides)

__all__ = ["FLAGS", "FLAG_ERROR_MASK", "InputError", "InputTypeError", "OutputError", "ParameterSet",
           "calibrate", "cuda_available", "data_directory", "element", "element_columns", "load_params", "mpm",
           "parse_params", "update"]
