"""The contour error of the verification job (issue 23): the distance of
the sampled positions from the programmed path (sim.job.path_errors), over
the telemetry cycles in which the reference moved
(drive_experiment.contour_error)."""

import numpy as np
import pytest
from contour.commission import drive_experiment as de
from contour.sim.job import path_errors


def test_path_errors_of_a_square():
    path = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
    act = np.array([[5, -1], [10.5, 5], [9, 9], [3, 10.25], [-2, 3], [11, 11]])
    # the corner (11, 11) is sqrt(2) from its nearest point (10, 10)
    want = [1, 0.5, 1, 0.25, 2, np.sqrt(2)]
    assert path_errors(path, act) == pytest.approx(want, abs=1e-12)


def test_contour_error_of_telemetry_cycles():
    # the reference runs along x at y = 0 (ferr = ref - pos); the machine is
    # 3 um to the side while it moves, 40 um off before and after (at rest:
    # not scored) and 5 um behind along the path (following, not contour)
    cycles = []
    for k in range(40):
        moving = 5 <= k < 35
        ref_x = min(max(k - 5, 0), 29) * 100_000
        pos = (ref_x - 5000, 3000 if moving else 40_000)
        cycles.append(
            {"pos0_nm": pos[0], "pos1_nm": pos[1], "ferr0_nm": ref_x - pos[0], "ferr1_nm": -pos[1]}
        )
    res = {"path_nm": np.array([[0.0, 0.0, 0.0], [2_900_000.0, 0.0, 0.0]]), "cycles": cycles}
    out = de.contour_error(res, [0, 1])
    assert out["max_contour_error_um"] == pytest.approx(3.0)
    assert out["rms_contour_error_um"] == pytest.approx(3.0)
    assert out["max_following_error_um"] == pytest.approx(5.0)  # largest axis's, as contour run


def test_too_few_telemetry_cycles_are_not_scored(monkeypatch):
    # e.g. CAN's 100 ms cycles over a 0.4 s square: the tool reports the
    # contour check as not scored (commands/tune._try_contour), not a number
    from contour.commands.tune import _try_contour
    from contour.errors import UserError

    cyc = [{"pos0_nm": k, "pos1_nm": 0, "ferr0_nm": 0, "ferr1_nm": 0} for k in range(5)]
    with pytest.raises(UserError, match="telemetry"):
        de.contour_error({"path_nm": np.zeros((2, 3)), "cycles": cyc}, [0, 1])

    class Client:
        pass

    def short(client, pair):
        return de.contour_error({"path_nm": np.zeros((2, 3)), "cycles": cyc}, list(pair))

    monkeypatch.setattr(de, "verify_contour", short)
    assert "telemetry" in _try_contour(Client(), (0, 1))["error"]
