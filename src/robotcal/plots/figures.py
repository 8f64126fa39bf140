"""Shared matplotlib plumbing: a headless backend, one look for every figure, atomic PNG writes."""

from __future__ import annotations

import math
import os
import struct
import sys
import zlib
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")  # never open a window; figures are files (pyplot too, where a caller imports it)

from matplotlib import ft2font  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg, get_hinting_flag  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.font_manager import fontManager, get_font  # noqa: E402

from robotcal.io.atomic import atomic_write_bytes  # noqa: E402

__all__ = ["DPI", "blank_figure", "new_figure", "save_figure", "set_margins", "encode_png"]


def __getattr__(name: str):
    """``plt``: matplotlib.pyplot, imported on first use (robotcal's figures do not need it: ~0.06 s)."""
    if name == "plt":
        import matplotlib.pyplot

        return matplotlib.pyplot
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


DPI = 110

#: zlib level of the PNG data. Level 3 on unfiltered rows: the demo's 23 figures encode in ~0.2 s of CPU
#: (Pillow's adaptive row filters and level 6, matplotlib's default: ~0.95 s) into 2.55 MB (Pillow: 2.63 MB).
PNG_COMPRESS_LEVEL = 3

#: The text chunk matplotlib writes into its PNGs (kept: the files say what drew them).
_SOFTWARE = f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/"


def new_figure(n_rows: int = 1, n_cols: int = 1, *, width_in: float = 6.4, height_in: float = 4.0, **kwargs):
    """A figure with an ``n_rows x n_cols`` grid of axes (``Figure.subplots`` semantics, constrained layout).

    The figures of robotcal pass ``layout=None`` and place their panels with :func:`set_margins`:
    constrained layout measures every artist on every draw (half the drawing time of a small figure).
    """
    kwargs.setdefault("layout", "constrained")
    figure = blank_figure(width_in, height_in, layout=kwargs.pop("layout"))
    return figure, figure.subplots(n_rows, n_cols, **kwargs)


def blank_figure(width_in: float, height_in: float, **kwargs) -> Figure:
    """An empty figure at :data:`DPI` on robotcal's Agg canvas (:class:`TextCacheCanvas`), outside pyplot's
    registry (nothing to close: it goes with its last reference)."""
    figure = Figure(figsize=(width_in, height_in), dpi=DPI, **kwargs)
    TextCacheCanvas(figure)
    return figure


#: Text layouts and extents kept for the process: (string, font, dpi, hinting, ...) -> value.
_LAYOUTS: dict[tuple, tuple[ft2font.FT2Font, tuple]] = {}
_EXTENTS: dict[tuple, tuple[ft2font.FT2Font, tuple[float, float, float]]] = {}
_CACHE_SIZE = 4096

#: The private Agg pieces :class:`TextCacheRenderer` builds on (matplotlib 3.11); without them it is plain Agg.
_CAN_CACHE_TEXT = hasattr(RendererAgg, "_draw_text_glyphs_and_boxes") and hasattr(ft2font.FT2Font, "_layout")

#: Glyph bitmaps kept for the process: (font, size, dpi, glyph, transform, pen position within its pixel in
#: 1/64, hinting, antialiasing) -> (font, bitmap, its corner relative to the pen's pixel). The font is kept with
#: its bitmaps, so its id stays its own. A forked process starts without them, as without the layouts:
#: matplotlib gives it new font objects (it clears its font cache at fork), so the kept keys would never match.
_GLYPHS: dict[tuple, tuple] = {}
_GLYPHS_KEPT = 20_000
RenderMode = getattr(ft2font, "RenderMode", None)
_CAN_KEEP_GLYPHS = (
    RenderMode is not None
    and hasattr(ft2font.FT2Font, "_render_glyph")
    and hasattr(ft2font.FT2Font, "_set_transform")
    and hasattr(RendererAgg, "_draw_text_glyphs_and_boxes")
)


if hasattr(os, "register_at_fork"):
    # a forked process (the figure worker, the histogram helpers) lays out its text with its own fonts:
    # matplotlib clears its font cache in the child too (an FT2Font shares its file offset with the parent)
    os.register_at_fork(after_in_child=lambda: (_LAYOUTS.clear(), _EXTENTS.clear(), _GLYPHS.clear()))


def _remember(cache: dict, key: tuple, value):
    if len(cache) >= _CACHE_SIZE:
        cache.clear()
    cache[key] = value
    return value


class TextCacheRenderer(RendererAgg):
    """Agg that lays out each distinct string once per process (font, size, dpi and hinting alike).

    Agg shapes a string (FreeType loads and hints every glyph) twice per draw of a text: once to
    measure it, once to draw it, and its measurement cache belongs to one renderer, that is one
    figure. The demo's figures draw 1240 strings, 448 distinct ("0", "50", axis labels on every
    panel): kept layouts and extents spare ~60 % of the shaping. The keys hold the font object Agg
    picks for the text (``_prepare_font``, as Agg does on every draw), so a change of font rcParams
    is a new key. Glyphs are still rendered at their own sub-pixel positions, so the pixels are
    Agg's (the tests compare them). Mathtext and TeX go to Agg unchanged.

    Two more things are kept, with the same pixels (tests compare with plain Agg):

    - each glyph's bitmap, for the process (:data:`_GLYPHS`): FreeType hints and renders a glyph alike
      wherever its pen falls in the same 1/64 of a pixel, and rendering was about a third of a figure's
      text drawing (the demo's joint figures: 2383 glyphs rendered for 5 figures);
    - a font's line metrics (ascent, descent, line gap), for one draw: ``Text._get_layout`` (matplotlib
      3.11) asks the renderer for them (``_get_font_height_metrics``, which Agg does not have) and otherwise
      finds the font file and reads two of its tables on every layout, three layouts per text and draw.
      They are computed as that fallback does, from the same tables in the same order of operations; the
      canvas forgets them when a draw asks for its renderer, so a change of font rcParams is seen.

    Built on private pieces of matplotlib 3.11's Agg (``FT2Font._layout``, ``FT2Font._render_glyph``,
    ``FT2Font._set_transform`` and ``RendererAgg._draw_text_glyphs_and_boxes``, the body of
    ``RendererAgg.draw_text``); where they are missing it is plain Agg.
    """

    def __init__(self, width, height, dpi, figure: Figure | None = None):
        super().__init__(width, height, dpi)
        self.figure = figure
        self.heights: dict = {}

    def _get_font_height_metrics(self, prop):
        dpi = self.dpi if self.figure is None else self.figure.dpi  # as Text._get_layout: the figure's
        key = (prop.copy(), dpi)
        if key not in self.heights:
            font = get_font(fontManager._find_fonts_by_props(prop))
            metrics = (None, None, None)  # Text._get_layout then measures "lp"
            for table_name, gap_key, ascent_key, descent_key in (
                ("OS/2", "sTypoLineGap", "sTypoAscender", "sTypoDescender"),
                ("hhea", "lineGap", "ascent", "descent"),
            ):
                table = font.get_sfnt_table(table_name)
                if table is None:
                    continue
                scale = 1 / font.get_sfnt_table("head")["unitsPerEm"] * prop.get_size_in_points() * dpi / 72
                metrics = (table[ascent_key] * scale, -table[descent_key] * scale, table[gap_key] * scale)
                break
            self.heights[key] = metrics
        return self.heights[key]

    def get_text_width_height_descent(self, s, prop, ismath):
        if ismath or not _CAN_CACHE_TEXT:
            return super().get_text_width_height_descent(s, prop, ismath)
        font = self._prepare_font(prop)  # the font file the rcParams pick for prop, at its size and dpi
        key = (s, id(font), prop.copy(), self.dpi, get_hinting_flag())
        entry = _EXTENTS.get(key)
        if entry is None:  # the font is kept with its entry: its id stays its own
            entry = _remember(_EXTENTS, key, (font, super().get_text_width_height_descent(s, prop, ismath)))
        return entry[1]

    def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if ismath or not _CAN_CACHE_TEXT:
            return super().draw_text(gc, x, y, s, prop, angle, ismath, mtext)
        features = mtext.get_fontfeatures() if mtext is not None else None
        language = mtext.get_language() if mtext is not None else None
        flags = get_hinting_flag()
        font = self._prepare_font(prop)  # as RendererAgg.draw_text: the font, cleared, at the size and dpi
        key = (s, id(font), prop.copy(), self.dpi, flags, _frozen(features), _frozen(language))
        entry = _LAYOUTS.get(key)
        if entry is None:  # the font is kept with its layout: its id stays its own
            layout = font._layout(s, flags=flags, features=features, language=language)
            entry = _remember(
                _LAYOUTS, key, (font, tuple((item.ft_object, item.glyph_index, item.x, item.y) for item in layout))
            )
        items = entry[1]
        size = prop.get_size_in_points()
        self._draw_text_glyphs_and_boxes(
            gc, x, y, angle, ((glyph_font, size, glyph, 0, 1, dx, dy) for glyph_font, glyph, dx, dy in items), []
        )


    def _draw_text_glyphs_and_boxes(self, gc, x, y, angle, glyphs, boxes):
        """Agg's glyph drawing (matplotlib 3.11 ``RendererAgg._draw_text_glyphs_and_boxes``, which this repeats
        step by step) with each glyph's bitmap kept for the process, see :data:`_GLYPHS`."""
        if boxes or not _CAN_KEEP_GLYPHS:  # mathtext's rules: Agg's own
            return super()._draw_text_glyphs_and_boxes(gc, x, y, angle, glyphs, boxes)
        cos = math.cos(math.radians(angle))
        sin = math.sin(math.radians(angle))
        load_flags = get_hinting_flag()
        antialiased = bool(gc.get_antialiased())
        rotation = 0x10000 * np.array([[cos, -sin], [sin, cos]])
        for font, size, glyph_index, slant, extend, dx, dy in glyphs:  # dy is upwards
            matrix = (rotation @ [[extend, extend * slant], [0, 1]]).round().astype(int)
            # the pen position in 1/64 pixel, FreeType's y upwards
            pen_x = round(0x40 * (x + dx * cos - dy * sin))
            pen_y = round(0x40 * (self.height - y + dx * sin + dy * cos))
            key = (id(font), size, self.dpi, glyph_index, matrix.tobytes(), pen_x & 0x3F, pen_y & 0x3F, load_flags,
                   antialiased)  # fmt: skip
            entry = _GLYPHS.get(key)
            if entry is None:
                font.set_size(size, self.dpi)
                font._set_transform(matrix, [pen_x, pen_y])
                bitmap = font._render_glyph(
                    glyph_index, load_flags, RenderMode.NORMAL if antialiased else RenderMode.MONO
                )
                buffer = np.array(bitmap.buffer)  # its own copy
                if not antialiased:
                    buffer *= 0xFF
                # the bitmap's corner relative to the whole pixel of the pen: an offset of whole pixels moves
                # the outline by whole pixels, so the same coverage lands in the same place relative to the pen
                entry = (font, buffer, bitmap.left - (pen_x >> 6), bitmap.top - (pen_y >> 6))
                if len(_GLYPHS) >= _GLYPHS_KEPT:
                    _GLYPHS.clear()
                _GLYPHS[key] = entry
            _, buffer, left, top = entry
            # draw_text_image's y is downwards & the bitmap bottom side
            self._renderer.draw_text_image(
                buffer, left + (pen_x >> 6), int(self.height) - (top + (pen_y >> 6)) + buffer.shape[0], 0, gc
            )
        return None


def _frozen(value):
    """A hashable form of a text's font features or language (None, a string or a list)."""
    if isinstance(value, list | tuple):
        return tuple(_frozen(item) for item in value)
    return value


class TextCacheCanvas(FigureCanvasAgg):
    """Agg canvas drawing with :class:`TextCacheRenderer` (same pixels as ``FigureCanvasAgg``)."""

    def get_renderer(self):
        width, height = self.get_width_height(physical=True)
        key = width, height, self.figure.dpi
        if self._lastKey != key:
            self.renderer = TextCacheRenderer(width, height, self.figure.dpi, self.figure)
            self._lastKey = key
        self.renderer.heights.clear()  # line metrics are kept for one draw
        return self.renderer


def set_margins(
    figure: Figure,
    *,
    left: float,
    right: float,
    bottom: float,
    top: float,
    wspace: float = 0.0,
    hspace: float = 0.0,
    cell: tuple[float, float] = (1.0, 1.0),
) -> None:
    """Fixed margins and gaps between panels, in inches (``cell``: a panel's width and height with its gap,
    to turn the gaps into matplotlib's fractions of a panel)."""
    width, height = figure.get_size_inches()
    figure.subplots_adjust(
        left=left / width,
        right=1.0 - right / width,
        bottom=bottom / height,
        top=1.0 - top / height,
        wspace=wspace / max(cell[0] - wspace, 1e-6),
        hspace=hspace / max(cell[1] - hspace, 1e-6),
    )


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(data, zlib.crc32(kind)))


def encode_png(rgba: np.ndarray, *, dpi: float = DPI, level: int = PNG_COMPRESS_LEVEL) -> bytes:
    """PNG bytes of an 8-bit RGBA image (colour type 6, no interlace), rows unfiltered, deflated at ``level``.

    Parameters
    ----------
    rgba : array_like of uint8, shape (height, width, 4)
        The pixels, top row first (Agg's buffer).
    dpi : float
        Stored as the pixel size (pHYs chunk, pixels per metre), as matplotlib does.
    level : int
        zlib compression level, 0-9.

    Notes
    -----
    Pillow, which matplotlib's PNG writer calls, chooses a filter for every row (it tries all five of the
    PNG specification) and deflates at level 6: most of a figure's PNG time. A plot is mostly runs of
    identical pixels, which deflate well without a filter; the file carries the same pixels (lossless;
    the tests decode it and compare with matplotlib's own PNG) and matplotlib's Software text.
    """
    rgba = np.asarray(rgba)
    if rgba.dtype != np.uint8 or rgba.ndim != 3 or rgba.shape[2] != 4 or 0 in rgba.shape[:2]:
        raise ValueError(
            f"rgba must be a non-empty uint8 array of shape (height, width, 4); got {rgba.dtype} {rgba.shape}"
        )
    height, width = rgba.shape[:2]
    rows = np.empty((height, 1 + 4 * width), dtype=np.uint8)
    rows[:, 0] = 0  # filter type 0 (None) on every row
    rows[:, 1:] = rgba.reshape(height, 4 * width)
    per_metre = round(dpi / 0.0254)
    return b"".join(
        [
            b"\x89PNG\r\n\x1a\n",
            _chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)),
            _chunk(b"tEXt", b"Software\x00" + _SOFTWARE.encode("latin-1")),
            _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
            _chunk(b"IDAT", zlib.compress(rows.data, level)),
            _chunk(b"IEND", b""),
        ]
    )


class _PixelSink:
    """A file for ``savefig(format="rgba")``: keeps the (height, width, 4) buffer Agg writes in one call."""

    def __init__(self):
        self.pixels: np.ndarray | None = None

    def write(self, data) -> int:
        view = memoryview(data)
        if self.pixels is not None or view.ndim != 3:
            raise RuntimeError("expected one write of Agg's (height, width, 4) RGBA buffer")
        self.pixels = np.array(view, dtype=np.uint8)  # a copy: the renderer reuses its buffer
        return view.nbytes

    def seek(self, offset: int, whence: int = 0) -> int:  # matplotlib takes an object with seek for a file
        raise OSError("not seekable")


def render_rgba(figure: Figure) -> np.ndarray:
    """The figure's pixels as ``savefig`` at :data:`DPI` draws them, shape (height, width, 4), uint8."""
    sink = _PixelSink()
    figure.savefig(sink, format="rgba", dpi=DPI)
    if sink.pixels is None:
        raise RuntimeError("savefig wrote no pixels")
    return sink.pixels


def save_figure(figure: Figure, path: str | Path) -> Path:
    """Write ``figure`` as PNG atomically (temp file + rename) and close it; returns the path.

    Drawn by ``savefig`` (Agg, :data:`DPI`) and encoded by :func:`encode_png`: the pixels of
    ``savefig(path, format="png")`` in about a fifth of its encoding time.
    """
    path = Path(path)
    try:
        pixels = render_rgba(figure)
    finally:
        if "matplotlib.pyplot" in sys.modules:  # a figure made by pyplot leaves its registry (robotcal's are not in it)
            sys.modules["matplotlib.pyplot"].close(figure)
    atomic_write_bytes(path, encode_png(pixels, dpi=DPI))
    return path
