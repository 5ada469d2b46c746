"""Prognosis: degradation histories, growth-law fits and RUL, trend analysis."""
