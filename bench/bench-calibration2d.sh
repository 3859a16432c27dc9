#!/usr/bin/env bash
# 2-D calibration of the simulated thesis table (docs/calibration.md
# "Calibration over the field", issue 22): `contour calibrate --sim
# lacerda_xy_field --grid X:-60:60:15,Y:-60:60:15 --apply` in process
# (simulated time, the drive's own firmware, link and flash), then again
# with 1 % of the link's frames dropped or corrupted.
#   calibration_2d_before_um          largest |systematic| error at the grid's
#                                     nodes before compensation, X and Y
#   calibration_2d_residual_um        largest |systematic| error after it, at the
#                                     cell centres (no calibration line there)
#   calibration_2d_residual_lossy_um  the same with 1 % of the frames lost
#   calibration_2d_field_s            simulated time of measuring one field
#                                     (36 lines, both passes of every line)
# Plot: build/bench/calibration2d/field.png (vectors before / after).
set -euo pipefail
cd "$(dirname "$0")/.."
py=.venv/bin/python
out=build/bench/calibration2d
mkdir -p "$out"
samples=${CAL2D_SAMPLES:-512}

$py - "$out" "$samples" <<'PY'
import contextlib, io, json, sys
from pathlib import Path
from contour import cli

out, samples = Path(sys.argv[1]), sys.argv[2]
machine = "hil_sim/machines/lacerda_xy_field.toml"


def grid(extra):
    buf = io.StringIO()
    argv = ["calibrate", "--sim", machine, "--grid", "X:-60:60:15,Y:-60:60:15",
            "--samples", samples, "--dwell-ms", "200", "--apply", "--json", "--no-progress",
            *extra]
    with contextlib.redirect_stdout(buf):
        rc = cli.main(argv)
    if rc != 0:
        raise SystemExit(f"bench-calibration2d: contour calibrate --grid failed ({rc}): "
                         f"{buf.getvalue().strip()}")
    return json.loads(buf.getvalue())


rep = grid(["--plot", str(out / "field.png"), "--map-out", str(out / "map.csv"),
            "--out", str(out / "nodes.csv")])
(out / "report.json").write_text(json.dumps(rep, indent=1))
lossy = grid(["--inject-loss", "0.01", "--seed", "7"])
print(f"calibration_2d_before_um: {rep['before_um']:.2f} um")
print(f"calibration_2d_residual_um: {rep['residual_um']:.2f} um")
print(f"calibration_2d_residual_lossy_um: {lossy['residual_um']:.2f} um")
print(f"calibration_2d_field_s: {rep['measure']['simulated_seconds']:.1f} s")
print(f"calibration_2d_lossy_frames_repeated: {lossy['frames_repeated_total']} frames")
PY
