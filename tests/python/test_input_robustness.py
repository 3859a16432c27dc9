"""Garbage profiles, machine files and G-code files: a one-line error (a
UserError, exit code 1) or a result, never a traceback nor a crash.

Every field of a profile and of a machine description is set, one at a time,
to each value of GARBAGE (NaN, infinities, 1e308, huge integers, wrong
types ...); random bytes stand in for binary files. The profile goes through
`contour estimate`, the machine description is loaded and applied to the
simulator (reaching its C set-up, where `encoder_lines = 1e19` used to raise
SIGFPE), a few through `contour sim run`.
"""

from __future__ import annotations

import math
import random

import pytest
from contour import cli
from contour.errors import UserError
from contour.estimation import MODELS, estimate_file
from contour.estimation import profile as profiles
from contour.sim import machine

GARBAGE = (
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-308",
    "0",
    "-1",
    "9223372036854775807",
    "1e19",
    '"text"',
    "true",
    "[1, 2]",
    "{ a = 1 }",
)

JOB = "G21 G90\nG1 X1 Y1 F600\nG4 P0.01\nG0 X0 Y0 C10\nG1 X2 C20\n"


def _cli(argv: list, capsys) -> int:
    """`contour ARGV` in process: any exception but a clean exit fails."""
    rc = cli.main(argv)
    capsys.readouterr()
    return rc


def _profile_cases() -> list:
    cases = []
    for table, fields in (
        ("motion", profiles.MOTION_FIELDS),
        ("axes.X", profiles.AXIS_FIELDS),
        ("axes.C", profiles.ROTARY_FIELDS),
        ("camargo2017", profiles.CAMARGO_FIELDS),
    ):
        for f in fields:
            for v in GARBAGE:
                cases.append((table, f.name, v))
    return cases


def test_every_profile_field_with_garbage_is_a_user_error_or_an_estimate(tmp_path):
    job = tmp_path / "job.ngc"
    job.write_text(JOB)
    prof = tmp_path / "p.toml"
    ok = refused = 0
    for table, key, value in _profile_cases():
        prof.write_text(f"[{table}]\n{key} = {value}\n")
        try:
            p = profiles.load(prof)
        except UserError:
            refused += 1
            continue
        for model in MODELS:
            try:
                summary, _ = estimate_file(str(job), p, model)
            except UserError:
                refused += 1
                continue
            assert math.isfinite(summary["total_s"]), (table, key, value, model)
            ok += 1
    assert ok and refused


def test_min_block_time_1e308_is_refused_by_name(tmp_path, capsys):
    job = tmp_path / "job.ngc"
    job.write_text(JOB)
    prof = tmp_path / "p.toml"
    prof.write_text("[motion]\nmin_block_time_s = 1e308\n")
    with pytest.raises(UserError, match="min_block_time_s"):
        profiles.load(prof)
    assert _cli(["estimate", str(job), "--profile", str(prof)], capsys) == 1


def _machine_cases() -> list:
    cases = []
    for key in sorted(machine.AXIS_KEYS - {"model"}):
        for v in GARBAGE:
            cases.append(f"[axis.all]\n{key} = {v}\n")
    for table, keys in (
        ("planner", machine.PLAN_KEYS),
        ("servo", machine.SERVO_KEYS),
        ("gains.axis", machine.GAIN_KEYS),
        ("gains.cec", machine.GAIN_KEYS),
        ("feedforward", machine.FF_KEYS),
    ):
        for key in sorted(keys):
            for v in GARBAGE:
                cases.append(f"[{table}]\n{key} = {v}\n")
    for key in ("tick_hz", "axes", "name", "axis", "planner", "gains"):
        for v in GARBAGE:
            cases.append(f"{key} = {v}\n")
    return cases


def test_every_machine_field_with_garbage_is_a_user_error_or_a_simulator(tmp_path):
    path = tmp_path / "m.toml"
    ok = refused = 0
    for text in _machine_cases():
        path.write_text(text)
        try:
            m = machine.load(str(path))
        except UserError:
            refused += 1
            continue
        try:  # accepted: the simulator's C set-up takes it or says no
            machine.apply(m)
            ok += 1
        except UserError:
            refused += 1
    assert ok and refused


def test_encoder_lines_1e19_is_a_load_time_error(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text("[axis.all]\nencoder_lines = 1e19\n")
    with pytest.raises(UserError, match="encoder_lines"):
        machine.load(str(path))
    job = tmp_path / "job.ngc"
    job.write_text("G21 G90\nG1 X0.1 F600\n")
    assert _cli(["sim", "run", str(job), "--machine", str(path)], capsys) == 1


def test_binary_files_are_user_errors(tmp_path, capsys):
    rnd = random.Random(17)
    job = tmp_path / "job.ngc"
    job.write_text(JOB)
    good_profile = "profiles/generic.toml"
    for i in range(5):
        blob = tmp_path / f"b{i}.bin"
        blob.write_bytes(bytes(rnd.randrange(256) for _ in range(rnd.randrange(1, 400))))
        assert _cli(["estimate", str(job), "--profile", str(blob)], capsys) == 1
        assert _cli(["sim", "run", str(job), "--machine", str(blob)], capsys) == 1
        assert _cli(["estimate", str(blob), "--profile", good_profile], capsys) in (0, 1)
        assert _cli(["sim", "run", str(blob)], capsys) in (0, 1)
