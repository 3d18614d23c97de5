"""Exported residual plots are for reports: axes, ticks, units, titles and the ±3σ band.

The HTML page is opened in a real headless browser (Chromium, from the Debian packages;
``make test`` installs it when apt-get is there) and captured as PNG: the picture must
show the shaded band, the axes frame and dark text (tick labels, titles) — not a blank
page. The text export must be plain characters. Residuals are synthetic and seeded
(white noise of a known σ, a few edited frames), so the test needs no fit.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from browser import chromium, screenshot

from gcs_core.units import ARCSEC
from gcs_tui.cli.export import export_residual_plots

one_arcsecond = ARCSEC
#: the band's fill (#f5d5a0 at 60 % over white) as the browser composes it, per channel ±
BAND_RGB = (249, 229, 198)
BAND_TOL = 6


def fake_analysis(seed: int = 7):
    """A star tracker (rad, σ = 8″) and a magnetometer (nT, σ = 25 nT), 600 frames each."""
    rng = np.random.default_rng(seed)
    t = np.arange(600.0) * 2.0

    def sensor(unit, sigma, comps):
        res = rng.normal(0.0, sigma, (t.size, len(comps)))
        edited = np.zeros(t.size, bool)
        edited[[50, 300]] = True
        res[edited] = 8 * sigma
        return SimpleNamespace(
            t=t,
            valid=np.ones(t.size, bool),
            edited=edited,
            residual=res,
            sigma=np.full(len(comps), sigma),
            unit=unit,
            components=comps,
            rms_normalized=1.0,
        )

    result = SimpleNamespace(
        residuals={"FHST1": sensor("rad", 8 * one_arcsecond, ("h", "v")), "TAM1": sensor("nT", 25.0, ("bx",))}
    )
    return SimpleNamespace(result=result, mission=SimpleNamespace(spec=SimpleNamespace(name="synthetic")))


def test_text_plots_have_no_terminal_codes(tmp_path):
    paths = export_residual_plots(fake_analysis(), tmp_path, fmt="txt")
    assert len(paths) == 3
    for p in paths:
        text = p.read_text(encoding="utf-8")
        assert "\x1b" not in text
        assert "residual [" in text and "t [s]" in text
        assert (os.stat(p).st_mode & 0o777) == 0o666 & ~_umask()


def test_html_page_is_self_contained_with_axes_units_and_band(tmp_path):
    (page,) = export_residual_plots(fake_analysis(), tmp_path, fmt="html")
    text = page.read_text(encoding="utf-8")
    assert "<script" not in text and "src=" not in text and "href=" not in text  # nothing external
    assert text.count("<svg") == 3
    assert "residual [arcsec]" in text and "residual [nT]" in text  # units from σ
    assert text.count("mission time t [s]") == 3 and text.count("±3σ band") == 3
    assert "FHST1 h: residual against time" in text


def _umask() -> int:
    m = os.umask(0o022)
    os.umask(m)
    return m


def read_png(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 of an 8-bit RGB or RGBA, non-interlaced PNG (what Chromium writes)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, ctype, _, _, interlace = header
    assert depth == 8 and ctype in (2, 6) and interlace == 0
    ch = 3 if ctype == 2 else 4
    raw = zlib.decompress(idat)
    stride = w * ch
    out = np.zeros((h, stride), np.int32)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        if f == 0:
            cur = line
        elif f == 2:
            cur = (line + prev) & 255
        else:  # sub, average, paeth need the running left pixel
            cur = np.zeros(stride, np.int32)
            for i in range(stride):
                a = cur[i - ch] if i >= ch else 0
                b = prev[i]
                c = prev[i - ch] if i >= ch else 0
                if f == 1:
                    pred = a
                elif f == 3:
                    pred = (a + b) // 2
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                cur[i] = (line[i] + pred) & 255
        out[y] = cur
        prev = cur
    return out.reshape(h, w, ch)[:, :, :3].astype(np.uint8)


def test_html_plots_render_in_a_real_browser(tmp_path):
    """Chromium draws the page: the band, the axes and the text are there in the pixels."""
    browser = chromium()
    if browser is None:
        pytest.skip(
            "no Chromium: `make test` installs it with apt-get (apt-get install chromium); "
            "this machine has neither it nor apt-get"
        )
    (page,) = export_residual_plots(fake_analysis(), tmp_path, fmt="html")
    png = tmp_path / "page.png"
    run = screenshot(browser, page, png, width=1000, height=1300)
    assert png.is_file(), run.stderr[-2000:]
    img = read_png(png).astype(int)
    h, w, _ = img.shape
    assert (h, w) == (1300, 1000)
    band = np.all(np.abs(img - np.array(BAND_RGB)) <= BAND_TOL, axis=2)
    dark = np.all(img < 120, axis=2)  # axes frame, ticks and text
    # three plots of 900×300 with bands spanning ±3σ of a ±~4σ axis: a lot of band pixels
    assert band.sum() > 3 * 0.4 * (900 - 250) * 150, band.sum()
    # the axes frame: long dark horizontal runs (the plots' top and bottom edges)
    frame = np.all(img < 170, axis=2)
    rows_with_frame = int(np.sum(frame.sum(axis=1) > 400))
    assert rows_with_frame >= 4, rows_with_frame
    # text (title, tick labels, axis labels) left of the data: dark pixels in the tick column
    assert dark[:, 20:75].sum() > 300


def test_html_has_the_plots_against_channels_with_binned_means(tmp_path):
    """A torquer channel of three levels: the TAM residual steps with it; the page shows the
    residual against the channel, with one bin mean per level."""
    a = fake_analysis()
    tam = a.result.residuals["TAM1"]
    mtb = np.resize([-60.0, 0.0, 60.0], tam.t.size)
    tam.residual[:, 0] += 0.4 * mtb
    a.problem = SimpleNamespace(
        sensor=lambda name: SimpleNamespace(geom=SimpleNamespace(aux={"mtb_x": mtb} if name == "TAM1" else {}))
    )
    (page,) = export_residual_plots(a, tmp_path, fmt="html")
    text = page.read_text(encoding="utf-8")
    assert text.count("<svg") == 4
    assert "TAM1 bx: residual against mtb_x" in text and "mtb_x [A m²]" in text
    assert text.count('r="4" fill="#117a65"') == 3 + 1  # three bin means and the legend's


def test_a_plot_is_bounded_however_many_points():
    """Decimation for display only: 200 000 points draw at most MAX_SVG_POINTS (the envelope:
    the extreme point stays)."""
    from gcs_tui.cli.export import MAX_SVG_POINTS, svg_plot

    rng = np.random.default_rng(3)
    n = 200_000
    t, y = np.arange(n, dtype=float), rng.normal(0.0, 1.0, n)
    y[123_457] = 3.9
    svg = svg_plot(t, y, np.zeros(n, bool), 1.0, "big", "nT")
    assert svg.count("<circle") <= MAX_SVG_POINTS + 1
    assert len(svg) < 200_000
    from gcs_tui.binning import envelope

    assert 123_457 in envelope(n, y, MAX_SVG_POINTS)  # the outlier is drawn
