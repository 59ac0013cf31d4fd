"""Run ``parcover`` in-process and check its outcome: a status of 0, 1 or 2, never an exception,
and on bad input (2) exactly one line ``parcover...: error: ...`` on stderr."""

from __future__ import annotations

import contextlib
import io
import tempfile
import traceback

from parcover_env.cli import main

_SCRATCH = tempfile.mkdtemp(prefix="parcover_cli_cwd_")


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """``(status, stdout, stderr)`` of ``parcover ARGV``; an exception escaping ``main`` fails the
    caller's test with the command line and the traceback."""
    out, err = io.StringIO(), io.StringIO()
    try:  # in a scratch directory: default outputs (frame.png, kinect_views/, runs/) land there
        with contextlib.chdir(_SCRATCH), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = main(argv)
    except BaseException as exc:  # noqa: BLE001 - any escape is the finding
        raise AssertionError(f"parcover {argv!r} raised {type(exc).__name__}: {exc}\n"
                             f"{''.join(traceback.format_exception(exc))}") from None
    return status, out.getvalue(), err.getvalue()


def check_outcome(argv: list[str], status: int, stderr: str) -> None:
    """Status 0 (done), 1 (ran; mission not accomplished) or 2 (bad input, one ``error:`` line)."""
    assert status in (0, 1, 2), f"parcover {argv!r}: status {status}"
    assert "Traceback" not in stderr, f"parcover {argv!r} printed a traceback:\n{stderr}"
    if status == 2:
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert len(lines) == 1, f"parcover {argv!r}: expected one error line, got:\n{stderr}"
        assert lines[0].startswith("parcover") and ": error: " in lines[0], lines[0]
