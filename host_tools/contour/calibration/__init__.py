"""Encoder calibration against a reference: the host side (docs/calibration.md).

- :mod:`contour.calibration.analysis`: per point mean error per direction,
  systematic error, hysteresis and random error (95 %), as defined in
  ``../shared/data/README.md``;
- :mod:`contour.calibration.tables`: table CSV, LinuxCNC COMP_FILE, the
  drive's compensation record, the import CSV;
- :mod:`contour.calibration.run`: the run over any transport (samples pulled
  with sequence numbers and CRCs, lost ones re-read or their point repeated),
  and the upload of a table;
- :mod:`contour.calibration.inproc`: the simulated drive in this process;
- :mod:`contour.calibration.faults`: frame loss and corruption injection;
- :mod:`contour.calibration.plot`: the error map as a PNG.
"""
