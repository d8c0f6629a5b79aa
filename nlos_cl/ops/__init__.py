"""Device operations, each kernels/<op>.cl + nlos_cl/ops/<op>.py (its definition, OpenCL
launcher and float64 NumPy twin, with example inputs and tolerances), listed in registry.py;
backend.py and opencl_backend.py run them by name as the NumPy twins or on an OpenCL device."""
from .base import Example, Operation
from .registry import OPERATIONS

__all__ = ["OPERATIONS", "Example", "Operation"]
