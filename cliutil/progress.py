"""Progress of a program's stages on stderr: tqdm bars on a terminal, log lines with counts when stderr is a file."""

from __future__ import annotations

import sys

from tqdm import tqdm


def log_stderr(message: str) -> None:
    """One log line on stderr, printed above any tqdm bar."""
    tqdm.write(message, file=sys.stderr)


def counted(items, step: str, progress):
    """Yield ``items``, calling ``progress(step, n, N)`` before the first and after each one is dealt with."""
    items = list(items)
    progress(step, 0, len(items))
    for done, item in enumerate(items, 1):
        yield item
        progress(step, done, len(items))


class StepProgress:
    """A ``progress(step, done, total)`` callback for one stage (counts from inside it: SfM's "extract", ...).

    On a terminal (``stream``, default stderr) each step gets a tqdm bar ``[stage] step``; otherwise ``log`` gets
    ``[stage] step n/N`` at every tenth of the way and at the end. Use as a context manager (closes the last bar).
    """

    def __init__(self, stage: str, log=log_stderr, stream=None):
        self.stage, self.log, self.stream = stage, log, stream or sys.stderr
        self.terminal = self.stream.isatty()
        self.step, self.bar, self.tenths = None, None, -1

    def __call__(self, step: str, done: int, total: int) -> None:
        if step != self.step:
            self.close()
            self.step, self.tenths = step, -1
            if self.terminal:
                self.bar = tqdm(total=total, desc=f"[{self.stage}] {step}", file=self.stream, leave=False)
        if self.bar is not None:
            self.bar.update(done - self.bar.n)
            return
        tenths = 10 * done // total if total else 10
        if tenths > self.tenths:
            self.tenths = tenths
            self.log(f"[{self.stage}] {step} {done}/{total}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> "StepProgress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
