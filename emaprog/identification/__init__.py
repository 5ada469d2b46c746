"""Fault identification: the objective over the Monitor Model, the GA, and its verdicts."""

from .run import Identification, check_sampling, identify_trace

__all__ = ["Identification", "check_sampling", "identify_trace"]
