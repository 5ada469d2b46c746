"""Strict YAML -> frozen models: scenarios, campaigns, histories, parameter sets."""
