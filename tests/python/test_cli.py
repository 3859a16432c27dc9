import subprocess
import sys

from contour import cli


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
