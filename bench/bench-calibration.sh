#!/usr/bin/env bash
# Calibration of the simulated drive over the real link (docs/calibration.md):
# `contour sim serve --machine lacerda_y_calibration --feedforward full` (the Y
# axis with Table 5.7's pitch error, backlash and random error), then
# `contour calibrate --axis Y --from -75 --to 75 --step 15 --apply` over its
# serial pseudo-terminal, in real time; re-measured on a 7.5 mm grid.
#   calibration_residual_um            largest |systematic| error after compensation
#   calibration_config_diff_um         largest difference of the measured mean
#                                      errors per direction from Table 5.7
#   calibration_max_systematic_um / _max_hysteresis_um / _mean_random_95_um
#                                      what the tool found before compensation
#   calibration_lossy_residual_um      the same run with 1 % of the frames dropped
#   calibration_lossy_frames_repeated  or corrupted in transit, and how many
#                                      requests were repeated because of it
#   calibration_seconds                wall time of the lossless run (measure +
#                                      upload + re-measure)
set -euo pipefail
cd "$(dirname "$0")/.."
py=.venv/bin/python
out=build/bench/calibration
mkdir -p "$out"

$py - "$out" <<'PY'
import json, sys, time
from pathlib import Path
from contour import cli
from contour.calibration import analysis, tables
from contour.sim.serve import spawn
import contextlib, io

out = Path(sys.argv[1])
data = Path("..") / "shared" / "data" / "lacerda1998" / "encoder_calibration_kgm101.csv"
configured = tables.read_thesis_table(str(data), "5.7")


def calibrate(port, extra):
    buf = io.StringIO()
    argv = ["calibrate", "--port", port, "--timeout", "0.2", "--axis", "Y", "--from", "-75",
            "--to", "75", "--step", "15", "--apply", "--json", "--no-progress", *extra]
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(buf):
        rc = cli.main(argv)
    if rc != 0:
        raise SystemExit(f"bench-calibration: contour calibrate failed ({rc})")
    return json.loads(buf.getvalue()), time.perf_counter() - t0


with spawn(["--machine", "lacerda_y_calibration", "--feedforward", "full"]) as s:
    rep, secs = calibrate(s.serial, ["--out", str(out / "table.csv"), "--plot",
                                     str(out / "error_map.png"), "--comp-file",
                                     str(out / "y.comp")])
with spawn(["--machine", "lacerda_y_calibration", "--feedforward", "full"]) as s:
    lossy, _ = calibrate(s.serial, ["--inject-loss", "0.01", "--seed", "7"])

em = analysis.ErrorMap(points=[analysis.from_summary(p["position_mm"], p["mean_err_pos_mm"],
                       p["std_pos_mm"], p["mean_err_neg_mm"], p["std_neg_mm"])
                       for p in rep["points"]])
d = analysis.compare(em, configured)
(out / "report.json").write_text(json.dumps({"lossless": rep, "lossy": lossy}, indent=1))
print(f"calibration_residual_um: {rep['residual']['residual_systematic_um']:.2f} um")
print(f"calibration_config_diff_um: "
      f"{max(d['max_diff_mean_err_pos_um'], d['max_diff_mean_err_neg_um']):.2f} um")
print(f"calibration_max_systematic_um: {rep['summary']['max_systematic_um']:.2f} um")
print(f"calibration_max_hysteresis_um: {rep['summary']['max_hysteresis_um']:.2f} um")
print(f"calibration_mean_random_95_um: {rep['summary']['mean_random_95_um']:.2f} um")
print(f"calibration_lossy_residual_um: {lossy['residual']['residual_systematic_um']:.2f} um")
inj = lossy["injected"]
print(f"calibration_lossy_frames_hit: {inj['dropped'] + inj['corrupted']} frames")
print(f"calibration_lossy_frames_repeated: {lossy['frames_repeated_total']} frames")
print(f"calibration_seconds: {secs:.1f} s")
PY
