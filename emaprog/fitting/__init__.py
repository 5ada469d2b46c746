"""Fitting the Monitor Model: to the Reference Model (calibration)."""
