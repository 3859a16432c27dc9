"""The 3 ms diagnosis (contour.sim.diagnose.why_table, docs/simulator.md "Why
no change of the CEC removes it"): at a tenth of its gains the CEC is still
worse than the PIDs at R 20 mm, 20 m/min on thesis.toml, less so than at
full gain; with the measurement made ideal and the start transient out it
is better."""

from __future__ import annotations

from contour.sim import diagnose

# thesis.toml (one sample per tick in the loops), scored on the instrument:
# the count cases (and R 10 mm 30 m/min, not at the stated feed)
SAMPLE_INSTRUMENT_WORSE = {(10, 30000), (20, 10000), (50, 10000), (50, 20000)}


def test_why_table_rows():
    rows = [
        r
        for r in diagnose.WHY_ROWS
        if r[0] != "CEC gains x 0.3" and r[0] != "X table as Y, 1e6 lines"
    ]
    lines = []
    out = diagnose.why_table(log=lines.append, rows=rows, cases=[(20, 20000)])
    (tenth,), (full,), (ideal,) = out
    assert tenth[0] == full[0]  # the PIDs do not depend on the CEC's gains
    assert full[0] < tenth[1] < full[1]  # worse at x 0.1, more so at x 1
    assert ideal[1] < ideal[0]  # ideal measurement, settled: the CEC is better
    assert "1.28 / 1.30" in lines[3]  # Ms at x 0.1 (X / Y)


def test_mean_measurement_leaves_only_the_table_vibration_as_scored():
    """docs/simulator.md "The 3 ms tick: the mean measurement": on
    thesis_mean.toml, with one sample of the table per tick, the CEC is
    worse than the PIDs (circular deviation) at R 10 mm 10 m/min, R 20 mm
    20 m/min and the run not at the stated feed (R 10 mm 30 m/min);
    scored on the table's mean over the tick or on the instrument (the
    table at the plant's substeps, its vibration whole, as `make run`
    scores) only at R 10 mm 30 m/min; thesis.toml (one sample
    per tick in the loops) stays worse in 6 on the tick sample, 4 on the
    tick mean, and on the instrument in the cases listed."""
    rows = [r for r in diagnose.MEAN_ROWS if r[2] == 0.5]
    (sample, sample_tm, sample_in, mean, mean_tm, mean_in) = diagnose.mean_table(
        log=lambda *_: None, rows=rows
    )

    def worse(pairs):
        return {c for c, (a, b) in zip(diagnose.NINE, pairs) if b > a}

    r10_30 = (10, 30000)
    assert worse(mean) == {(10, 10000), r10_30, (20, 20000)}
    assert worse(mean_tm) == {r10_30}
    assert worse(mean_in) == {r10_30}
    assert len(worse(sample_tm)) == 4
    assert len(worse(sample)) == 6
    assert worse(sample_in) == SAMPLE_INSTRUMENT_WORSE
