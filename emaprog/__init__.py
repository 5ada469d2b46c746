"""emaprog: model-based fault identification and prognostics for flight-control EMAs.

The Python API (what the command line does, returning typed results)::

    import emaprog
    trace = emaprog.simulate("configs/fig10-multiple-faults.yaml")    # DataFrame, units in attrs
    report = emaprog.identify(trace)                                   # emaprog.Report
    report.estimate["friction"], report.health

See docs/reference.md ("Python API") for every function and result type.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("emaprog")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

from .api import (  # noqa: E402 - __version__ first: the API stamps it on every result
    Calibration,
    Commissioned,
    Report,
    SweepOutcome,
    Trend,
    calibrate,
    check,
    commission,
    convert,
    identify,
    simulate,
    sweep,
    trend,
)
from .config.parameters import load as load_parameters  # noqa: E402
from .config.scenario import load_scenario  # noqa: E402
from .errors import InputError  # noqa: E402
from .faults import CATALOGUE  # noqa: E402

__all__ = [
    "CATALOGUE",
    "Calibration",
    "Commissioned",
    "InputError",
    "Report",
    "SweepOutcome",
    "Trend",
    "__version__",
    "calibrate",
    "check",
    "commission",
    "convert",
    "identify",
    "load_parameters",
    "load_scenario",
    "simulate",
    "sweep",
    "trend",
]
