"""The software and machine a result was computed on, for its provenance.

Identification's answer on a unit of another form moves with the last digits of the
machine's arithmetic (docs/explanation/validation-and-speed.md: robustness-pwm on two
machines, friction within tolerance 81.5 and 86 %), so a campaign's or a report's figures
name the numerical libraries and the CPU they came from.
"""

from __future__ import annotations

import platform
from functools import cache
from importlib.metadata import PackageNotFoundError, version

#: The libraries whose arithmetic the numbers depend on.
LIBRARIES = ("numpy", "scipy", "numba", "llvmlite", "pandas", "pyarrow", "deap")


@cache
def environment() -> dict[str, str]:
    """Python, each of :data:`LIBRARIES`' version, the machine and the CPU LLVM compiles for."""
    from llvmlite import binding

    found = {"python": platform.python_version()}
    for name in LIBRARIES:
        try:
            found[name] = version(name)
        except PackageNotFoundError:  # pragma: no cover - every one is a dependency
            found[name] = "not installed"
    found["machine"] = platform.machine()
    found["cpu"] = binding.get_host_cpu_name()
    return found
