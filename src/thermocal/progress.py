"""Progress bars for long runs (rich), shared by every command."""

from __future__ import annotations


def progress_bar():
    """A rich progress bar (count, items per second, time left) on stderr; vanishes when done.
    Only on a terminal: into a pipe or a log, rich would leave an empty line behind it, before
    the command's one line."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        ProgressColumn,
        TextColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class FramesPerSecond(ProgressColumn):
        def render(self, task):  # noqa: D102 - rich's column protocol
            speed = task.finished_speed or task.speed
            return Text(f"{speed:.1f}/s" if speed else "")

    console = Console(stderr=True)
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        FramesPerSecond(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
