"""Commissioning of an axis (issue 23): excitation records, identification of
the axis model from them, and (later) tuning from the identified model."""
