import json
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from contour import cli
from contour.errors import UsageError, UserError
from contour.image import ImageError
from contour.link.client import DriveError
from contour.link.transport import LinkError

ROOT = Path(__file__).resolve().parents[2]


def test_help_lists_program(capsys):
    try:
        cli.main(["--help"])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    assert "usage: contour" in out


def test_no_command_is_an_error():
    assert cli.main([]) == 2


def test_module_entry_point_runs():
    proc = subprocess.run(
        [sys.executable, "-m", "contour", "--version"], capture_output=True, text=True
    )
    assert proc.returncode == 0
    assert proc.stdout.startswith("contour ")


def test_command_line_mistakes_are_one_error_line(capsys):
    """argparse's own errors (a value that is not a number, an unknown choice, a
    missing option) are one `contour: error:` line and exit code 2, no usage block."""
    cases = [
        (["sim", "circle", "--radius", "abc", "--feed", "1", "--controller", "pid"], "--radius"),
        (["sim", "circle", "--radius", "1", "--feed", "1", "--controller", "foo"], "'foo'"),
        (["sim", "circle", "--feed", "1", "--controller", "pid"], "required: --radius"),
        (["no-such-command"], "'no-such-command'"),
    ]
    for argv, detail in cases:
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("contour: error: ") and err.count("\n") == 1, err
        assert detail in err and "usage:" not in err, err


def test_link_timeout_is_checked_before_the_port_is_opened(capsys):
    for value in ("-1", "0", "nan"):
        assert cli.main(["info", "--port", "/nonexistent", "--timeout", value]) == 2
        err = capsys.readouterr().err
        assert err.startswith("contour: error: --timeout must be in (0, 60] s"), err


# ---- exit codes and --json errors (docs/conventions.md) -------------------------------


def _drive_error() -> DriveError:
    from contour import protocol_gen as pg

    f = {"code": int(pg.ErrorCode.FAULTED), "arg": 1, "lo": 0, "hi": 0}
    return DriveError("queue_block", f, "drive refused queue_block: a fault is latched")


@pytest.mark.parametrize(
    "exc, code, kind",
    [
        (UsageError("--x must be 1..2"), 2, "usage"),
        (LinkError("no reply"), 1, "link"),
        (_drive_error(), 1, "drive"),
        (ImageError("image is for board 2"), 1, "image"),
        (UserError("job.nc:3: malformed number"), 1, "input"),
        (FileNotFoundError(2, "No such file or directory", "a.nc"), 1, "file"),
        (OSError(28, "No space left on device", "/dev/full"), 1, "file"),
        (KeyboardInterrupt(), 130, "interrupted"),
    ],
)
def test_every_error_class_ends_with_its_exit_code(monkeypatch, capsys, exc, code, kind):
    """One table maps the error classes to exit codes; each class is raised
    from inside a command, and reported as one line or, with --json, as one
    JSON object on stdout."""
    import contour.commands.info as info

    def boom(args):
        raise exc

    monkeypatch.setattr(info, "run", boom)
    assert cli.main(["info", "--port", "x"]) == code
    out = capsys.readouterr()
    assert out.out == "" and out.err.count("\n") == 1 and "Traceback" not in out.err
    assert cli.main(["info", "--port", "x", "--json"]) == code
    out = capsys.readouterr()
    assert out.err == ""
    assert json.loads(out.out) == {
        "error": {"kind": kind, "message": cli._message(exc), "exit_code": code}
    }


def test_link_failure_is_exit_1_and_json(capsys):
    assert cli.main(["info", "--port", "/nonexistent/tty"]) == 1
    assert "cannot open serial port /nonexistent/tty" in capsys.readouterr().err
    assert cli.main(["get", "comm_timeout_ms", "--port", "/nonexistent/tty", "--json"]) == 1
    err = json.loads(capsys.readouterr().out)["error"]
    assert err["kind"] == "link" and err["exit_code"] == 1


def test_usage_errors_under_json_are_json(capsys):
    for argv in (
        ["info", "--json", "--bogus"],  # argparse's own
        ["info", "--json", "--port", "x", "--timeout", "-1"],  # our validation
        ["scan", "--json", "--can", "socketcan:can0@500000"],  # '@' is not a bitrate
    ):
        assert cli.main(argv) == 2, argv
        out = capsys.readouterr()
        err = json.loads(out.out)["error"]
        assert err["kind"] == "usage" and err["exit_code"] == 2 and out.err == "", argv


def test_sigterm_runs_the_command_clean_up_and_exits_143(tmp_path):
    """SIGTERM raises into the command (as Ctrl-C does) so that its finally
    blocks run; the exit code is 128 + 15."""
    marker = tmp_path / "cleaned"
    script = textwrap.dedent(
        f"""
        import sys, time
        from contour import cli
        import contour.commands.info as info
        def run(args):
            try:
                print("ready", flush=True)
                time.sleep(30)
            finally:
                open({str(marker)!r}, "w").close()
        info.run = run
        sys.exit(cli.main(["info", "--port", "x"]))
        """
    )
    p = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert p.stdout.readline().strip() == "ready"
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=20)
    assert p.returncode == 143, err
    assert marker.exists()
    assert err.strip() == "contour: error: terminated (signal 15)"


# ---- the drive-link options: the same on every command, python-can's naming ------------

LINK_OPTIONS = {"--port", "--can", "--interface", "--channel", "--bitrate", "--node", "--timeout"}


def _subparsers(parser):
    import argparse

    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            yield from a.choices.items()


def test_every_link_command_has_the_same_link_options():
    parser = cli.build_parser()
    cmds = dict(_subparsers(parser))
    for name in ("info", "get", "set", "run", "monitor", "calibrate", "flash", "scan"):
        opts = {o for a in cmds[name]._actions for o in a.option_strings}
        assert opts >= LINK_OPTIONS, (name, LINK_OPTIONS - opts)
    # the older helper for commands not yet on the parent adds the same options
    import argparse

    from contour.link.client import add_link_arguments

    p = argparse.ArgumentParser()
    add_link_arguments(p)
    assert {o for a in p._actions for o in a.option_strings} >= LINK_OPTIONS


def _target(argv, monkeypatch, env=None):
    from contour.link.options import target_from_args

    for k in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(k, raising=False)
    for k, v in (env or {}).items():
        monkeypatch.setenv(k, v)
    args = cli.build_parser().parse_args(["info", *argv])
    return target_from_args(args)


def test_can_bus_named_as_python_can_does(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))  # no python-can config file
    # short form: the channel verbatim, slcan's @N is python-can's serial baud
    t = _target(["--can", "slcan:/dev/pts/1@115200", "--bitrate", "500000"], monkeypatch)
    assert t.can["interface"] == "slcan" and t.can["channel"] == "/dev/pts/1@115200"
    assert t.can["bitrate"] == 500000
    t = _target(["--interface", "virtual", "--channel", "bus7", "--node", "3"], monkeypatch)
    assert (t.can["interface"], t.can["channel"], t.node) == ("virtual", "bus7", 3)
    # python-can's environment fills in what the command line does not say
    t = _target([], monkeypatch, {"CAN_INTERFACE": "virtual", "CAN_CHANNEL": "envbus"})
    assert (t.can["interface"], t.can["channel"]) == ("virtual", "envbus")
    t = _target(["--channel", "mine"], monkeypatch, {"CAN_INTERFACE": "virtual"})
    assert t.can["channel"] == "mine"
    # and so does its config file
    (tmp_path / ".canrc").write_text("[default]\ninterface = virtual\nchannel = filebus\n")
    t = _target([], monkeypatch)
    assert (t.can["interface"], t.can["channel"]) == ("virtual", "filebus")
    # --port wins over nothing else: with a CAN option it is a usage error
    assert _target(["--port", "/dev/x"], monkeypatch).port == "/dev/x"


@pytest.mark.parametrize(
    "argv, message",
    [
        ([], "choose the drive"),
        (["--port", "/dev/x", "--can", "virtual:a"], "not both"),
        (["--can", "virtual:a", "--channel", "b"], "short form"),
        (["--can", "socketcan:can0@500000"], "--bitrate"),
        (["--can", "slcan:/dev/x@fast"], "serial baud"),
        (["--interface", "nosuchbus", "--channel", "a"], "nosuchbus"),
        (["--interface", "virtual"], "no channel"),
        (["--can", "virtual:a", "--bitrate", "0"], "--bitrate 0"),
        (["--can", "virtual:a", "--node", "0"], "--node 0"),
    ],
)
def test_link_option_mistakes_are_usage_errors(monkeypatch, tmp_path, capsys, argv, message):
    monkeypatch.setenv("HOME", str(tmp_path))
    with pytest.raises(UsageError, match=message.replace("(", r"\(")):
        _target(argv, monkeypatch)
    assert cli.main(["info", *argv]) == 2
    assert message in capsys.readouterr().err


# ---- one unit convention in JSON output (docs/conventions.md) ---------------------------

UNIT_SUFFIXES = ("_mm", "_um", "_nm", "_s", "_ms", "_us", "_hz", "_mm_min", "_mm_s", "_um_s")
UNITLESS = {
    "blocks", "edges", "edge_mismatch_ticks", "planner_blocks", "ticks",  # counts
    "segments", "lines", "program_blocks", "lookahead_blocks", "chords",
}  # fmt: skip


def _check_units(obj: dict, where: str) -> None:
    for k, v in obj.items():
        if isinstance(v, (int, float)) and not isinstance(v, bool) and k not in UNITLESS:
            assert k.endswith(UNIT_SUFFIXES), f"{where}: field {k!r} does not name its unit"


def test_sim_json_fields_name_their_unit_and_agree(tmp_path, capsys):
    """`sim circle` and `sim run` report the contour error under the same
    name in the same unit (um); every number names its unit."""
    argv = ["sim", "circle", "--radius", "2", "--feed", "6000", "--controller", "pid", "--json"]
    assert cli.main(argv) == 0
    circle = json.loads(capsys.readouterr().out)
    job = tmp_path / "l.nc"
    job.write_text("G1 X1 F3000\nG1 Y1\n")
    assert cli.main(["sim", "run", str(job), "--json"]) == 0
    run = json.loads(capsys.readouterr().out)
    _check_units(circle, "sim circle")
    _check_units(run, "sim run")
    assert circle["max_contour_error_um"] == pytest.approx(circle["max_contour_error_mm"] * 1e3)
    assert circle["circular_deviation_um"] > 0 and run["max_contour_error_um"] > 0
    # the field names other tools read are kept
    for k in ("max_contour_error_mm", "revolution_s", "circular_deviation_mm"):
        assert k in circle
    assert "max_following_error_um" in run
    prof = str(ROOT / "profiles" / "hermle_c1200v_itnc530.toml")
    assert cli.main(["estimate", str(job), "--profile", prof, "--json"]) == 0
    est = json.loads(capsys.readouterr().out)
    _check_units(est, "estimate")
    _check_units(est["options"], "estimate options")
    assert "min_feed_mm_min" in est


def test_the_boot_client_is_library_code():
    """commands/flash.py parses and prints; the procedure lives in
    contour.link.boot, which knows nothing of the command line."""
    import ast

    import contour.commands.flash as cmd
    import contour.link.boot as boot

    tree = ast.parse(Path(cmd.__file__).read_text())
    assert not [n.name for n in tree.body if isinstance(n, ast.ClassDef)]
    imported = set()
    for n in ast.walk(ast.parse(Path(boot.__file__).read_text())):
        if isinstance(n, ast.ImportFrom):
            imported.add(n.module)
        elif isinstance(n, ast.Import):
            imported |= {a.name for a in n.names}
    assert not {m for m in imported if m == "argparse" or m.startswith("contour.commands")}
    assert hasattr(boot, "BootClient") and hasattr(boot, "flash")


def test_a_closed_stdout_is_no_error_line(tmp_path):
    """`contour ... | head -0`: the reader went away; exit 1 without an
    error line or a traceback."""
    import os

    r, w = os.pipe()
    os.close(r)
    argv = ["sim", "circle", "--radius", "2", "--feed", "6000", "--controller", "pid"]
    p = subprocess.run(
        [sys.executable, "-m", "contour", *argv], stdout=w, stderr=subprocess.PIPE, text=True
    )
    os.close(w)
    assert p.returncode == 1 and p.stderr == "", p.stderr


def test_readme_examples_ship_and_run_on_the_simulated_drive(capsys):
    """Every job the README names is in examples/ and runs on the simulated
    drive without a fault; the headline figure names its options."""
    import re

    root = ROOT
    readme = (root / "README.md").read_text()
    named = set(re.findall(r"examples/([\w-]+\.nc)", readme))
    assert {"square.nc", "circle.nc", "pocket.nc"} <= named
    assert "job.nc" not in readme
    assert "--feedforward full" in readme
    for name in sorted(named):
        path = root / "examples" / name
        assert path.is_file(), name
        assert cli.main(["sim", "run", str(path), "--feedforward", "full", "--json"]) == 0
        rep = json.loads(capsys.readouterr().out)
        assert rep["faults"] == [] and rep["blocks"] >= 4 and not rep["skipped"], (name, rep)
