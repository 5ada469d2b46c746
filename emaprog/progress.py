"""Progress reporting: a rich bar on a terminal, plain log lines otherwise."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Protocol


class Advance(Protocol):
    def __call__(self, steps: int = 1, **fields: object) -> None: ...


@contextmanager
def task(description: str, total: int, enabled: bool = True) -> Iterator[Advance]:
    """Yield ``advance(steps, **fields)``; draws a bar only when stderr is a TTY.

    Off a terminal it prints at most ten plain lines per task to stderr, so logs
    of CI runs and sweeps stay readable.
    """
    if not enabled:
        yield lambda steps=1, **fields: None
        return
    if sys.stderr.isatty():
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[info]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            transient=False,
        ) as bar:
            handle = bar.add_task(description, total=total, info="")

            def advance(steps: int = 1, **fields: object) -> None:
                info = " ".join(f"{k}={v}" for k, v in fields.items())
                bar.update(handle, advance=steps, info=info)

            yield advance
        return
    state = {"done": 0, "next": 0.0, "start": time.monotonic()}

    def advance_plain(steps: int = 1, **fields: object) -> None:
        state["done"] += steps
        fraction = state["done"] / max(total, 1)
        if fraction >= state["next"] or state["done"] >= total:
            state["next"] = fraction + 0.1
            info = " ".join(f"{k}={v}" for k, v in fields.items())
            elapsed = time.monotonic() - state["start"]
            print(
                f"{description}: {state['done']}/{total} {info} ({elapsed:.1f} s)".rstrip(),
                file=sys.stderr,
                flush=True,
            )

    yield advance_plain


Callback = Callable[..., None]
