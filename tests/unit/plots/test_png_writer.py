"""robotcal's PNG writer gives the pixels of matplotlib's own PNG (decoded by Pillow, an independent
decoder), a valid file (every chunk's CRC checked by Pillow's verify), and matplotlib's metadata; the
convergence figure's plain-text log labels name the same numbers as matplotlib's mathtext labels."""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np
import pytest
from matplotlib.ticker import LogFormatterSciNotation
from PIL import Image

from robotcal.plots.figures import DPI, encode_png, new_figure, plt, render_rgba, save_figure
from robotcal.plots.refine import PlainLogFormatter, plot_convergence


def _decode(data: bytes) -> np.ndarray:
    image = Image.open(io.BytesIO(data))
    image.load()
    assert image.mode == "RGBA"
    return np.asarray(image)


def _figure_with_text_lines_and_alpha():
    figure, axes = new_figure(1, 2, width_in=5.3, height_in=3.1, layout=None)
    x = np.linspace(0.0, 10.0, 200)
    axes[0].plot(x, np.sin(x), label="sin")
    axes[0].fill_between(x, -0.5, 0.5, alpha=0.3, color="tab:red")
    axes[0].set_title("µm ± σ, J1 [deg]")
    axes[0].legend()
    axes[1].scatter(x, np.cos(x), c=x, s=4)
    axes[1].set_xlabel("reading [deg]")
    figure.patch.set_alpha(0.4)  # a translucent background: the alpha channel must come through
    return figure


def test_png_has_the_pixels_of_matplotlibs_png(tmp_path):
    figure = _figure_with_text_lines_and_alpha()
    reference = io.BytesIO()
    figure.savefig(reference, format="png", dpi=DPI)
    expected = _decode(reference.getvalue())
    pixels = render_rgba(figure)
    assert pixels.shape == expected.shape == (round(3.1 * DPI), round(5.3 * DPI), 4)
    assert np.unique(expected[..., 3]).size > 1  # the test image does exercise the alpha channel
    np.testing.assert_array_equal(_decode(encode_png(pixels)), expected)
    path = save_figure(figure, tmp_path / "figure.png")
    np.testing.assert_array_equal(_decode(path.read_bytes()), expected)
    with Image.open(path) as image:
        image.verify()  # chunk CRCs, IEND
    with Image.open(path) as image:
        assert image.info["Software"].startswith("Matplotlib version")
        assert image.info["dpi"] == pytest.approx((DPI, DPI), abs=0.01)


@pytest.mark.parametrize("shape", [(1, 1, 4), (3, 7, 4), (64, 33, 4)])
def test_png_round_trips_random_pixels(shape):
    rgba = np.random.default_rng(sum(shape)).integers(0, 256, shape, dtype=np.uint8)
    for level in (0, 3, 9):
        np.testing.assert_array_equal(_decode(encode_png(rgba, level=level)), rgba)


def test_png_chunks_and_header():
    data = encode_png(np.zeros((5, 9, 4), dtype=np.uint8))
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    offset, kinds = 8, []
    while offset < len(data):
        (length,) = struct.unpack(">I", data[offset : offset + 4])
        kind, body = data[offset + 4 : offset + 8], data[offset + 8 : offset + 8 + length]
        (crc,) = struct.unpack(">I", data[offset + 8 + length : offset + 12 + length])
        assert crc == zlib.crc32(kind + body), kind
        kinds.append(kind)
        if kind == b"IHDR":
            assert struct.unpack(">IIBBBBB", body) == (9, 5, 8, 6, 0, 0, 0)
        offset += 12 + length
    assert offset == len(data)
    assert kinds == [b"IHDR", b"tEXt", b"pHYs", b"IDAT", b"IEND"]


@pytest.mark.parametrize(
    "pixels", [np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4, 4), np.float32), np.zeros((0, 4, 4), np.uint8)]
)
def test_png_refuses_what_is_not_rgba8(pixels):
    with pytest.raises(ValueError, match="uint8 array of shape"):
        encode_png(pixels)


def _mathtext_value(label: str) -> float:
    """The number a LogFormatterSciNotation mathtext label shows: ``$\\mathdefault{4\\times10^{-2}}$`` -> 0.04."""
    body = label.removeprefix("$\\mathdefault{").removesuffix("}$")
    coefficient, _, power = body.rpartition("\\times")
    base, exponent = power.split("^{")
    return float(coefficient or 1.0) * float(base) ** int(exponent.rstrip("}"))


def _plain_value(label: str) -> float:
    digits = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")
    coefficient, _, power = label.rpartition("×")
    base, exponent = power[:2], power[2:].translate(digits)
    return float(coefficient or 1.0) * float(base) ** int(exponent)


@pytest.mark.parametrize("limits", [(0.013, 0.12), (1e-16, 3.0), (2e-3, 4e-3), (50.0, 2e5)])
def test_plain_log_labels_name_the_same_numbers(limits):
    figure, axis = plt.subplots()
    axis.semilogy([0, 1], limits)
    for ticks, locator in ((axis.yaxis.get_majorticklocs(), "major"), (axis.yaxis.get_minorticklocs(), "minor")):
        mathtext, plain = LogFormatterSciNotation(), PlainLogFormatter()
        for formatter in (mathtext, plain):
            formatter.set_axis(axis.yaxis)
        expected, got = mathtext.format_ticks(ticks), plain.format_ticks(ticks)
        if locator == "major":
            assert any(expected)  # the case does label ticks
        assert [bool(label) for label in got] == [bool(label) for label in expected], locator  # same ticks labelled
        for want, have in zip(expected, got, strict=True):
            if want:
                assert "$" not in have
                assert _plain_value(have) == pytest.approx(_mathtext_value(want), rel=1e-12), (want, have)
    plt.close(figure)


def test_convergence_figure_uses_no_mathtext(tmp_path, monkeypatch):
    import robotcal.plots.refine as refine_figures

    drawn = []
    monkeypatch.setattr(refine_figures, "save_figure", lambda figure, path: drawn.append(figure) or path)
    histories = {
        "points": {"criterion": "points", "rms_mm": np.array([0.13, 0.011, 0.0109, 0.0109])},
        "distances": {"criterion": "distances", "rms_mm": np.array([0.05, 0.015, 0.015])},
    }
    plot_convergence(histories, tmp_path / "convergence.png")
    figure = drawn[0]
    figure.canvas.draw()
    labels = [label.get_text() for axis in figure.axes for label in axis.get_yticklabels(which="both")]
    assert any("10⁻" in label for label in labels)
    assert not any("$" in label for label in labels)
    assert [axis.get_title() for axis in figure.axes][0].startswith("points criterion")
    plt.close(figure)
