"""The hardware-in-the-loop simulator, driven from Python.

The simulation itself runs in C (``hil_sim/sim.c`` in ``build/host/libcontour.so``):
the firmware's drive application, planner, interpolator, decoders and servo
loops, closed with the axis models. This package only configures it
(:mod:`contour.sim.machine`), queues motion, runs ticks and scores the result
(:mod:`contour.sim.circle`, :mod:`contour.sim.job`); :mod:`contour.sim.tuning`
is the frequency-domain analysis behind the shipped gain sets.
"""
