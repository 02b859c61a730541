"""Scatter and line charts drawn with Pillow, for benchmark PNGs without matplotlib.

A :class:`Chart` is one panel: title, axis labels, linear or log axes, and series of points
(markers, optionally joined) or lines. :func:`save_charts` lays panels out in a grid and writes
one PNG. Only what the benchmarks need: no clipping beyond the data range, no date axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

#: Distinguishable colors, in the order series take them.
PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
           (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))
MARKERS = ("circle", "square", "triangle", "diamond", "cross")

_MARGIN_LEFT, _MARGIN_TOP, _MARGIN_BOTTOM, _LEGEND_WIDTH = 70, 30, 48, 190
_MARKER_RADIUS = 4


@dataclass
class Series:
    """Points (xs[i], ys[i]) in data units, drawn as markers and/or a polyline.

    ``highlight`` (same length as xs, optional) draws a ring round the flagged points.
    """

    label: str
    xs: list[float]
    ys: list[float]
    color: tuple[int, int, int]
    marker: str | None = "circle"
    line: bool = False
    dashed: bool = False
    highlight: list[bool] | None = None


@dataclass
class Chart:
    """One panel: a title, axis labels, axis kinds and its series."""

    title: str
    x_label: str
    y_label: str
    log_x: bool = False
    log_y: bool = False
    series: list[Series] = field(default_factory=list)

    def add(self, series: Series) -> Series:
        """Append ``series`` and return it."""
        self.series.append(series)
        return series


def color(index: int) -> tuple[int, int, int]:
    """The ``index``-th palette color (cycling)."""
    return PALETTE[index % len(PALETTE)]


def save_charts(charts: list[Chart], path: str | Path, *, columns: int | None = None,
                panel_size: tuple[int, int] = (620, 400)) -> None:
    """Draw ``charts`` in a grid (``columns`` per row, default all in one row) to a PNG."""
    columns = columns or max(1, len(charts))
    rows = max(1, -(-len(charts) // columns))
    width, height = panel_size
    image = Image.new("RGB", (columns * width, rows * height), "white")
    draw = ImageDraw.Draw(image)
    for i, chart in enumerate(charts):
        _draw_panel(image, draw, chart, ((i % columns) * width, (i // columns) * height),
                    panel_size)
    image.save(path)


# ---------------------------------------------------------------------------- drawing
def _font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):
        return ImageFont.load_default()


class _Axis:
    """Maps data values on one axis to pixels, with tick positions and labels."""

    def __init__(self, values: list[float], log: bool, lo_px: float, hi_px: float) -> None:
        self.log = log
        t = [self._t(v) for v in values if self.usable(v)] or [0.0, 1.0]
        lo, hi = min(t), max(t)
        if hi - lo < 1e-12:
            lo, hi = lo - 0.5, hi + 0.5
        pad = 0.06 * (hi - lo)
        self.lo, self.hi = lo - pad, hi + pad
        self.lo_px, self.hi_px = lo_px, hi_px

    def _t(self, value: float) -> float:
        return math.log10(value) if self.log else value

    def usable(self, value) -> bool:
        """Whether ``value`` can be drawn: a finite number, and positive on a log axis."""
        return (isinstance(value, (int, float)) and math.isfinite(value)
                and (value > 0 or not self.log))

    def px(self, value: float) -> float:
        frac = (self._t(value) - self.lo) / (self.hi - self.lo)
        return self.lo_px + frac * (self.hi_px - self.lo_px)

    def ticks(self) -> list[float]:
        if not self.log:
            return self._linear_ticks(self.lo, self.hi)
        decades = range(math.floor(self.lo), math.ceil(self.hi) + 1)
        for steps in ((1,), (1, 2, 5), tuple(range(1, 10))):
            vals = [m * 10.0 ** d for d in decades for m in steps]
            vals = [v for v in vals if self.lo <= self._t(v) <= self.hi]
            if len(vals) >= 3:
                return vals
        # Less than a factor of ~2 across the axis: evenly spaced values read better.
        return [v for v in self._linear_ticks(10 ** self.lo, 10 ** self.hi) if v > 0]

    def _linear_ticks(self, lo: float, hi: float) -> list[float]:
        raw = (hi - lo) / 5
        mag = 10 ** math.floor(math.log10(raw))
        step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
        first = math.ceil(lo / step) * step
        vals = [first + k * step for k in range(int((hi - first) / step) + 1)]
        return [v for v in vals if v > 0 or not self.log]


def _label(value: float) -> str:
    magnitude = abs(value)
    for suffix, scale in (("M", 1e6), ("k", 1e3)):
        if magnitude >= scale:
            return f"{value / scale:g}{suffix}"
    if magnitude and magnitude < 1e-3:
        return f"{value:.0e}"
    return f"{round(value, 6):g}"


def _draw_panel(image: Image.Image, draw: ImageDraw.ImageDraw, chart: Chart,
                origin: tuple[int, int], size: tuple[int, int]) -> None:
    ox, oy = origin
    left, top = ox + _MARGIN_LEFT, oy + _MARGIN_TOP
    right, bottom = ox + size[0] - _LEGEND_WIDTH, oy + size[1] - _MARGIN_BOTTOM
    small, normal = _font(11), _font(13)
    xs = [x for s in chart.series for x in s.xs]
    ys = [y for s in chart.series for y in s.ys]
    x_axis = _Axis(xs, chart.log_x, left, right)
    y_axis = _Axis(ys, chart.log_y, bottom, top)

    for tick in x_axis.ticks():
        px = x_axis.px(tick)
        draw.line([(px, top), (px, bottom)], fill=(232, 232, 232))
        draw.text((px, bottom + 4), _label(tick), fill="black", font=small, anchor="mt")
    for tick in y_axis.ticks():
        py = y_axis.px(tick)
        draw.line([(left, py), (right, py)], fill=(232, 232, 232))
        draw.text((left - 5, py), _label(tick), fill="black", font=small, anchor="rm")
    draw.rectangle([left, top, right, bottom], outline="black")
    draw.text(((left + right) / 2, oy + 8), chart.title, fill="black", font=normal, anchor="mt")
    draw.text(((left + right) / 2, bottom + 22), chart.x_label, fill="black", font=small,
              anchor="mt")
    _vertical_text(image, chart.y_label, (ox + 6, (top + bottom) / 2), small)

    for series in chart.series:
        points = [(x_axis.px(x), y_axis.px(y)) for x, y in zip(series.xs, series.ys)
                  if x_axis.usable(x) and y_axis.usable(y)]
        if series.line and len(points) > 1:
            _polyline(draw, points, series.color, series.dashed)
        if series.marker:
            flags = series.highlight or [False] * len(series.xs)
            for (x, y), flag in zip(zip(series.xs, series.ys), flags):
                if x_axis.usable(x) and y_axis.usable(y):
                    at = (x_axis.px(x), y_axis.px(y))
                    _marker(draw, at, series.marker, series.color)
                    if flag:
                        r = _MARKER_RADIUS + 3
                        draw.ellipse([at[0] - r, at[1] - r, at[0] + r, at[1] + r],
                                     outline="black", width=1)
    _legend(draw, chart.series, (right + 10, top), small)


def _polyline(draw: ImageDraw.ImageDraw, points, fill, dashed: bool) -> None:
    if not dashed:
        draw.line(points, fill=fill, width=2)
        return
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        length = math.hypot(x1 - x0, y1 - y0)
        for start in range(0, int(length), 10):
            a, b = start / length, min(start + 6, length) / length
            draw.line([(x0 + a * (x1 - x0), y0 + a * (y1 - y0)),
                       (x0 + b * (x1 - x0), y0 + b * (y1 - y0))], fill=fill, width=2)


def _marker(draw: ImageDraw.ImageDraw, at, kind: str, fill) -> None:
    x, y, r = at[0], at[1], _MARKER_RADIUS
    if kind == "square":
        draw.rectangle([x - r, y - r, x + r, y + r], fill=fill)
    elif kind == "triangle":
        draw.polygon([(x, y - r - 1), (x - r - 1, y + r), (x + r + 1, y + r)], fill=fill)
    elif kind == "diamond":
        draw.polygon([(x, y - r - 1), (x + r + 1, y), (x, y + r + 1), (x - r - 1, y)], fill=fill)
    elif kind == "cross":
        draw.line([(x - r, y - r), (x + r, y + r)], fill=fill, width=2)
        draw.line([(x - r, y + r), (x + r, y - r)], fill=fill, width=2)
    else:
        draw.ellipse([x - r, y - r, x + r, y + r], fill=fill)


def _legend(draw: ImageDraw.ImageDraw, series: list[Series], at, font) -> None:
    x, y = at
    for s in series:
        if not s.label:
            continue
        if s.line:
            _polyline(draw, [(x, y + 6), (x + 22, y + 6)], s.color, s.dashed)
        if s.marker:
            _marker(draw, (x + 11, y + 6), s.marker, s.color)
        draw.text((x + 28, y), s.label, fill="black", font=font)
        y += 16


def _vertical_text(image: Image.Image, text: str, at, font) -> None:
    probe = ImageDraw.Draw(image)
    box = probe.textbbox((0, 0), text, font=font)
    label = Image.new("RGBA", (box[2] - box[0] + 2, box[3] - box[1] + 4), (255, 255, 255, 0))
    ImageDraw.Draw(label).text((-box[0], -box[1]), text, fill="black", font=font)
    turned = label.rotate(90, expand=True)
    image.paste(turned, (int(at[0]), int(at[1] - turned.height / 2)), turned)
