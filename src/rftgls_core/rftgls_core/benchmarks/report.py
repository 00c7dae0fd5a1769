"""docs/performance.md's table: one run, its machine line and the command that wrote it.

`rftgls bench --markdown FILE` writes the run between two marker lines of FILE and leaves the
rest (the prose around the table) as it is; a new FILE holds only the table.
"""
from __future__ import annotations

import math
from pathlib import Path

from .machine import describe
from .registry import Run
from .timing import Figure, format_value

BEGIN = '<!-- rftgls bench: begin (generated; edit outside the markers) -->'
END = '<!-- rftgls bench: end -->'
_DERIVED = ('_share_of_peak', '_vs_numpy')


def _cell(f: Figure | None) -> str:
    if f is None or not math.isfinite(f.value):
        return ''
    return f'{f.value:.2f}' if f.name.endswith('_share_of_peak') else f'{f.value:.3g}x'


def table(run: Run, command: str) -> str:
    """The markdown block: machine line, command, one row per measured figure."""
    by_name = {f.name: f for f in run.figures}
    lines = [BEGIN, '',
             f"Measured on: {describe(run.machine)}; CPU target `{run.machine['cpu_target']}`; "
             f"load {run.machine.get('loadavg_1min_end', '?')} at the end.", '',
             f'Command: `{command}`', '',
             '| figure | value | unit | share of peak | vs numpy | budget | how measured |',
             '| --- | ---: | --- | ---: | ---: | --- | --- |']
    for f in run.figures:
        if f.name.endswith(_DERIVED):
            continue
        share = _cell(by_name.get(f'{f.name}_share_of_peak'))
        ratio = _cell(by_name.get(f'{f.name}_vs_numpy'))
        note = f.note.replace('|', '/')
        lines.append(f'| `{f.name}` | {format_value(f)} | {f.unit} | {share} | {ratio} | '
                     f'{f.budget} | {note} |')
    lines += ['', END]
    return '\n'.join(lines)


def write_markdown(path: str | Path, run: Run, command: str) -> None:
    """Put the run's table between the markers of `path` (create the file if missing)."""
    p = Path(path)
    block = table(run, command)
    text = p.read_text() if p.exists() else ''
    if BEGIN in text and END in text:
        head, _, rest = text.partition(BEGIN)
        _, _, tail = rest.partition(END)
        text = head + block + tail
    elif text:
        raise ValueError(f'{p} has no "{BEGIN}" ... "{END}" markers: not overwriting it')
    else:
        text = block + '\n'
    p.write_text(text)
