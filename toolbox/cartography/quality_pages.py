"""Pages of the quality report: the sections' blocks (tables, text, figures) flowed onto A4 pages
(PDF, matplotlib) or into one HTML page. A section starts on the current page when its heading
and a few rows still fit, tables continue on the next page with their header repeated, and
figures are scaled to the text width: no page is left nearly empty."""

from __future__ import annotations

import base64
import io
import textwrap
from html import escape
from pathlib import Path

PAGE_W, PAGE_H = 8.27, 11.69  # A4 portrait, inches
MARGIN = 0.6
TEXT_W = PAGE_W - 2 * MARGIN
FONT = 8.0  # pt: >= 6 pt at print size
LINE = 0.165  # in per text line at FONT
CHAR_W = 0.6 * FONT / 72  # mean character width of the sans-serif font, in
STATUS_COLOURS = {"pass": "#d5f5e3", "FAIL": "#f5b7b1", "not checked": "#eaecee"}


def _wrap(text: str, width_in: float) -> list[str]:
    chars = max(8, int(width_in / CHAR_W))
    return textwrap.wrap(str(text), chars, break_long_words=True) or [""]


def _column_widths(header: list[str], rows: list[list[str]]) -> list[float]:
    """Column widths (in) from the longest content, capped so that long cells wrap."""
    longest = [max([len(header[i]) + 1] + [min(len(r[i]), 48) for r in rows]) + 3
               for i in range(len(header))]
    total = sum(longest)
    return [TEXT_W * n / total for n in longest]


class PdfFlow:
    """Places blocks top to bottom on A4 pages of a PdfPages file."""

    def __init__(self, pdf, title: str):
        import matplotlib.pyplot as plt

        self.plt, self.pdf, self.title = plt, pdf, title
        self.page = None
        self.pages = 0
        self.y = 0.0  # inches from the top

    def new_page(self) -> None:
        self.finish_page()
        self.page = self.plt.figure(figsize=(PAGE_W, PAGE_H))
        self.pages += 1
        self.y = MARGIN
        self._text(MARGIN, PAGE_H - 0.35, self.title, size=7, colour="#555555")
        self._text(PAGE_W - MARGIN, PAGE_H - 0.35, f"page {self.pages}", size=7,
                   colour="#555555", ha="right")

    def finish_page(self) -> None:
        if self.page is not None:
            self.pdf.savefig(self.page)
            self.plt.close(self.page)
            self.page = None

    def room(self) -> float:
        return PAGE_H - MARGIN - self.y

    def ensure(self, height: float) -> None:
        if self.page is None or height > self.room():
            self.new_page()

    def _text(self, x: float, y_from_top: float, text: str, size: float = FONT,
              colour: str = "black", bold: bool = False, ha: str = "left") -> None:
        self.page.text(x / PAGE_W, 1 - y_from_top / PAGE_H, text, fontsize=size, color=colour,
                       fontweight="bold" if bold else "normal", ha=ha, va="top")

    def heading(self, text: str, size: float = 13) -> None:
        self.ensure(0.45 + 4 * LINE)  # a heading never ends a page
        self.y += 0.1
        self._text(MARGIN, self.y, text, size=size, bold=True)
        self.y += size / 72 * 1.6

    def paragraph(self, text: str) -> None:
        for line in _wrap(text, TEXT_W):
            self.ensure(LINE)
            self._text(MARGIN, self.y, line)
            self.y += LINE
        self.y += 0.08

    def table(self, header: list[str], rows: list[list[str]]) -> None:
        from matplotlib.patches import Rectangle

        widths = _column_widths(header, rows)

        def draw_row(cells: list[str], bold: bool, fill: str | None) -> None:
            wrapped = [_wrap(c, w - 0.08) for c, w in zip(cells, widths)]
            height = max(len(w) for w in wrapped) * LINE + 0.05
            if height > self.room():
                self.new_page()
                if not bold:
                    draw_row(header, True, "#d6dbdf")
            x = MARGIN
            for lines, w, cell in zip(wrapped, widths, cells):
                colour = STATUS_COLOURS.get(cell) if not bold else fill
                colour = colour or fill
                if colour:
                    self.page.patches.append(Rectangle(
                        (x / PAGE_W, 1 - (self.y + height) / PAGE_H), w / PAGE_W,
                        height / PAGE_H, transform=self.page.transFigure, color=colour,
                        zorder=-1))
                for k, line in enumerate(lines):
                    self._text(x + 0.04, self.y + 0.03 + k * LINE, line, bold=bold)
                x += w
            self.y += height

        self.ensure(3 * LINE)
        draw_row(header, True, "#d6dbdf")
        for i, row in enumerate(rows):
            draw_row(row, False, "#f4f6f6" if i % 2 else None)
        self.y += 0.15

    def figure(self, fig) -> None:
        import matplotlib.image as mpimg

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=150)
        buf.seek(0)
        image = mpimg.imread(buf)
        fw, fh = fig.get_size_inches()
        scale = min(1.0, TEXT_W / fw, (PAGE_H - 2 * MARGIN - 0.2) / fh)
        w, h = fw * scale, fh * scale
        if self.page is not None and 0.65 * (h + 0.1) <= self.room() < h + 0.1:
            w, h = w * (self.room() - 0.1) / h, self.room() - 0.1  # shrunk a little to fit
        self.ensure(h + 0.1)
        ax = self.page.add_axes([(MARGIN + (TEXT_W - w) / 2) / PAGE_W,
                                 1 - (self.y + h) / PAGE_H, w / PAGE_W, h / PAGE_H])
        ax.imshow(image, interpolation="antialiased")
        ax.set_axis_off()
        self.y += h + 0.15


def write_pdf(path: str | Path, title: str, sections) -> int:
    """The sections flowed onto A4 pages; returns the page count."""
    from matplotlib.backends.backend_pdf import PdfPages

    with PdfPages(path, metadata={"Title": title, "Creator": "photogrammetry-toolbox"}) as pdf:
        flow = PdfFlow(pdf, title)
        flow.new_page()
        flow.heading(title, size=16)
        for sec in sections:
            flow.heading(sec.title)
            for block in sec.blocks:
                if block[0] == "table":
                    flow.table(block[1], block[2])
                elif block[0] == "text":
                    flow.paragraph(block[1])
                else:
                    flow.figure(block[1])
        flow.finish_page()
        return flow.pages


def write_html(path: str | Path, title: str, sections) -> None:
    """One HTML page: the same sections, figures embedded as PNG."""
    def table(header, rows):
        head = "".join(f"<th>{escape(h)}</th>" for h in header)
        body = "".join("<tr>" + "".join(
            f"<td class='{escape(c).replace(' ', '_')}'>{escape(c)}</td>" for c in row) + "</tr>"
            for row in rows)
        return f"<table><tr>{head}</tr>{body}</table>"

    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{escape(title)}"
             "</title><style>body{font-family:sans-serif;max-width:1000px;margin:auto}"
             "table{border-collapse:collapse;margin:0.5em 0}th,td{padding:2px 8px;"
             "text-align:left;border-bottom:1px solid #ddd}th{background:#d6dbdf}"
             ".pass{background:#d5f5e3}.FAIL{background:#f5b7b1}"
             ".not_checked{background:#eaecee}img{max-width:100%}</style></head><body>",
             f"<h1>{escape(title)}</h1>"]
    for sec in sections:
        parts.append(f"<h2 id='{sec.key}'>{escape(sec.title)}</h2>")
        for block in sec.blocks:
            if block[0] == "table":
                parts.append(table(block[1], block[2]))
            elif block[0] == "text":
                parts.append(f"<p>{escape(block[1])}</p>")
            else:
                buf = io.BytesIO()
                block[1].savefig(buf, format="png", dpi=110)
                data = base64.b64encode(buf.getvalue()).decode("ascii")
                parts.append(f"<figure class='{sec.key}'><img src='data:image/png;base64,"
                             f"{data}'></figure>")
    parts.append("</body></html>")
    Path(path).write_text("\n".join(parts), encoding="utf-8")
