"""Running the ``gva`` command line inside a test: its exit status and what it printed."""

from __future__ import annotations

import contextlib
import io

from experiments.cli import main


def gva(*args: object) -> tuple[int, str, str]:
    """Runs ``gva`` in this process: (exit status, stdout, stderr); argparse's exits too."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main([str(a) for a in args])
        except SystemExit as exit:
            status = int(exit.code or 0)
    return status, out.getvalue(), err.getvalue()
