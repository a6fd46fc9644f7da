"""The error every aerostereo program reports as one line with exit code 2 (:func:`cliutil.program.run_cli`): bad
input, raised by library code and command lines alike, so the library need not import the command-line helpers."""

from __future__ import annotations


class BadInput(ValueError):
    """Bad user input or an impossible request: printed as one line, exit code 2.

    The message names the file (with line or byte offset where known) or the argument, and what was expected.
    """
