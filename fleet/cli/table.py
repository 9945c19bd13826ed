"""Tables as `kubectl get` prints them, laid out for rich consoles (`fleet status`, plans, diffs)."""

from __future__ import annotations

import sys
from typing import Any

from rich.cells import cell_len
from rich.control import strip_control_codes
from rich.text import Span, Text


class Table:
    """Rows of cells (strings, or rich Text for colour) under upper-case headers and a rule,
    columns three spaces apart, a bold title above, as `kubectl get` prints them.

    Every column is as wide as its widest cell.  When that is wider than a screen, columns are
    two spaces apart instead (`fleet status` of a small fleet then fits 80 columns), and the last
    column (a reason, a value: free text) is wrapped within what is left of the screen, down to
    MIN_LAST characters; narrower than that, the lines are left long, for the terminal to wrap
    (as kubectl's are).  Laid out here, not with rich's Table: that measures, wraps and pads
    each cell on its own (1.3 s for `fleet status` of 1,000 robots on 100 agents, against
    0.19 s here), and on an 80-column screen it folded every column, `running` included."""

    GAP, NARROW_GAP = "   ", "  "  # between columns; the narrow one where the wide does not fit
    MIN_LAST = 20

    def __init__(self, columns: tuple[str, ...], title: str | None = None) -> None:
        self.columns = [column.upper() for column in columns]
        self.title = title
        self.rows: list[tuple[Any, ...]] = []
        self.styles: list[str] = []

    def add_row(self, *cells: Any, style: str = "") -> None:
        """A row of cells, blank ones added to fill it; `style` (rich's: "bold", "dim") for the
        whole row, under its cells' own."""
        if len(cells) > len(self.columns):
            raise ValueError(f"{len(cells)} cells for {len(self.columns)} columns")
        self.rows.append(cells + ("",) * (len(self.columns) - len(cells)))
        self.styles.append(style)

    def __rich_console__(self, console, options):
        # Each cell as its lines, each line as (text, spans): a cell of several lines (a value
        # printed as a block) takes as many lines of its row.
        rows = [[_cell_lines(cell) for cell in row] for row in self.rows]
        widths = [
            max([cell_len(header), *(cell_len(line[0]) for row in rows for line in row[i])])
            for i, header in enumerate(self.columns)
        ]
        # Into a pipe or a file a row stays one line, however long, for grep and awk (as kubectl's).
        screen = options.max_width if console.is_terminal else sys.maxsize
        gap = self.GAP
        if sum(widths) + len(gap) * (len(widths) - 1) > screen:
            gap = self.NARROW_GAP
        room = screen - sum(widths[:-1]) - len(gap) * (len(widths) - 1)
        if widths[-1] > room >= self.MIN_LAST:
            for row in rows:
                row[-1] = _wrapped(row[-1], room, console)
            widths[-1] = room
        width = sum(widths) + len(gap) * (len(widths) - 1)
        if self.title:
            yield Text(self.title, style="bold")
        # One Text for the whole table, its colours as spans: a Text per cell or per line costs
        # rich more than the layout itself.
        header = gap.join(name.ljust(size) for name, size in zip(self.columns, widths, strict=True)).rstrip()
        lines = [header, "\u2500" * width]
        spans = [Span(0, len(header), "bold")]
        position = len(header) + 1 + width + 1  # where the next line starts in the text
        for row, style in zip(rows, self.styles, strict=True):
            for k in range(max(len(cell) for cell in row)):
                parts: list[str] = []
                cell_spans: list[Span] = []
                column = position
                for cell, size in zip(row, widths, strict=True):
                    text, text_spans = cell[k] if k < len(cell) else ("", [])
                    cell_spans.extend(span.move(column) for span in text_spans)
                    padding = " " * (size - cell_len(text)) + gap
                    parts += (text, padding)
                    column += len(text) + len(padding)
                line = "".join(parts).rstrip()
                if style:  # the row's style first: its cells' own go over it
                    spans.append(Span(position, position + len(line), style))
                spans += cell_spans
                lines.append(line)
                position += len(line) + 1
        yield Text("\n".join(lines), spans=spans)


def _cell_lines(cell: Any) -> list[tuple[str, list[Any]]]:
    """A cell's lines as rich would print them (control codes such as \\r dropped), each with
    its style spans."""
    if not isinstance(cell, Text):
        return [(line, []) for line in strip_control_codes(str(cell)).split("\n")]
    if "\n" in cell.plain:
        return [line for part in cell.split("\n") for line in _cell_lines(part)]
    text = strip_control_codes(cell.plain)
    if len(text) != len(cell.plain):  # the spans' offsets would no longer match: drop them
        return [(text, [])]
    return [(text, ([Span(0, len(text), cell.style)] if cell.style else []) + list(cell.spans))]


def _wrapped(lines: list[tuple[str, list[Any]]], width: int, console) -> list[tuple[str, list[Any]]]:
    """The lines wrapped at words (long words cut) to `width` cells."""
    if all(cell_len(text) <= width for text, _ in lines):
        return lines
    wrapped = []
    for text, spans in lines:
        for line in Text(text, spans=spans).wrap(console, width, overflow="fold"):
            line.rstrip()
            wrapped += _cell_lines(line)
    return wrapped
