"""Plots of a tracked sequence (tracking.plots) from a small synthetic track.

Where a curve must be is worked out by hand from the panel layout: a panel is 860 × 220 px
(``PANEL_SIZE``) with margins left 74, right 170, top 30, bottom 40 (``MARGINS``), so the plot area
is 616 × 150 px from (74, 30); frame ``x`` of 0..10 lands at ``u = 74 + 61.6 x`` and value ``y`` at
``v = 30 + 150 (y1 − y) / (y1 − y0)``, where ``[y0, y1]`` is the span of the round ticks that cover
the data (worked out per plot in the comments).
Tolerances: curves are drawn anti-aliased, 2 px thick, with sub-pixel end points, so a curve pixel
is looked for within 2 px of where the value puts it, and "away from the curve" means more than
5 px from it; a pixel "has" a curve's colour when each channel is within 40 of it (anti-aliasing
blends the line's edge with the white background and grey grid).
"""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from photomodel.exchange.files import atomic_write_bytes, encode_png
from tracking.plots import COLORS, MARGINS, PANEL_SIZE, line_panel, nice_ticks, stack_panels, track_plots

T = 11  # frames 0..10
FRAMES = np.arange(T)
SMILE = FRAMES / 10.0  # mouth: the smile ramps 0 → 1, neutral 1 → 0 (they cross at frame 5)
YAW = np.linspace(-20.0, 20.0, T)  # deg
RMS = np.array([0.02, 0.03, 0.025, 0.04, 0.05, 0.045, 0.06, 0.1, 0.05, 0.04, 0.03])  # frame 7 diverged
DIVERGED_RMS = 0.08


def u_of(frame):
    return 74 + 616 * frame / 10.0


def v_of(value, y0, y1):
    return 30 + 150 * (y1 - value) / (y1 - y0)


def near_colour(img, u, v, colour, radius=2, tol=40):
    """Whether a pixel within ``radius`` of (u, v) has ``colour`` (each channel within ``tol``)."""
    r, c = int(round(v)), int(round(u))
    patch = img[r - radius : r + radius + 1, c - radius : c + radius + 1].astype(int)
    return bool(np.any(np.all(np.abs(patch - colour) <= tol, axis=-1)))


def colour_rows_in_column(img, u, colour, tol=40):
    """Rows of the plot area (30..180) where column ``u`` has ``colour``."""
    col = img[30:181, int(round(u))].astype(int)
    return 30 + np.flatnonzero(np.all(np.abs(col - colour) <= tol, axis=-1))


@pytest.fixture(scope="module")
def records():
    out = []
    for i in FRAMES:
        out.append(
            {
                "frame": int(i),
                "weights": {
                    "mouth": {"neutral": 1.0 - SMILE[i], "smile": SMILE[i]},
                    "brows": {"neutral": 0.75, "smile": 0.25},
                },
                "head_rotation_deg": [0.0, YAW[i], 5.0],
                "centre_mm": [2.0, -1.0, 650.0 + i],
                "rms": RMS[i],
                "diverged": bool(RMS[i] > DIVERGED_RMS),
            }
        )
    return out


@pytest.fixture(scope="module")
def plots(records):
    return track_plots(records, ["mouth", "brows"], ["neutral", "smile"], diverged_rms=DIVERGED_RMS)


def test_layout_constants_are_the_ones_worked_out_here():
    assert PANEL_SIZE == (860, 220) and MARGINS == (74, 170, 30, 40)  # see module docstring


def test_plots_are_written_with_the_expected_sizes(plots, tmp_path):
    # one 860 × 220 panel per region (2), per rotation plot (1), per translation axis (3), for the RMS (1)
    expected = {
        "weights.png": (440, 860),
        "rotation.png": (220, 860),
        "translation.png": (660, 860),
        "rms.png": (220, 860),
    }
    assert set(plots) == set(expected)
    for name, (h, w) in expected.items():
        assert plots[name].shape == (h, w, 3) and plots[name].dtype == np.uint8, name
        path = atomic_write_bytes(tmp_path / name, encode_png(plots[name]))  # as tracking.batch writes them
        back = Image.open(io.BytesIO(path.read_bytes()))
        assert back.size == (w, h) and back.mode == "RGB", name
        np.testing.assert_array_equal(np.asarray(back), plots[name])


def test_weight_curves_lie_where_the_weights_say(plots):
    img = plots["weights.png"]
    mouth, brows = img[:220], img[220:]
    # weights span [0, 1] (ylim (0, 1) too): ticks 0, 0.5, 1 → y0 = 0, y1 = 1, v = 180 − 150 w
    for i in FRAMES:
        if i == 5:
            continue  # the curves cross here: the later one covers the earlier
        for k, w in enumerate((1.0 - SMILE[i], SMILE[i])):  # neutral (first colour), smile (second)
            assert near_colour(mouth, u_of(i), v_of(w, 0.0, 1.0), COLORS[k]), (i, k)
            rows = colour_rows_in_column(mouth, u_of(i), COLORS[k])
            assert np.all(np.abs(rows - v_of(w, 0.0, 1.0)) <= 5), (i, k, rows)  # nowhere else in the column
    # brows: flat at 0.75 and 0.25 → rows 67.5 and 142.5
    for i in (1, 4, 9):
        assert near_colour(brows, u_of(i), 67.5, COLORS[0]) and near_colour(brows, u_of(i), 142.5, COLORS[1])


def test_rotation_curves_lie_where_the_angles_say(plots):
    img = plots["rotation.png"]
    # values −20..20: ticks of step 10 → y0 = −20, y1 = 20; pitch 0 → row 105, roll 5 → row 86.25
    for i in FRAMES:
        assert near_colour(img, u_of(i), v_of(YAW[i], -20.0, 20.0), COLORS[1]), i
        if abs(YAW[i]) > 8:  # away from where yaw crosses pitch and roll
            assert near_colour(img, u_of(i), 105.0, COLORS[0]), i
            assert near_colour(img, u_of(i), 86.25, COLORS[2]), i


def test_rms_curve_threshold_and_diverged_marks(plots):
    img = plots["rms.png"]
    # RMS 0.02..0.1 with ylim from 0: ticks of step 0.05 → y0 = 0, y1 = 0.1, v = 180 − 1500 rms
    for i in FRAMES:
        v = v_of(RMS[i], 0.0, 0.1)
        assert near_colour(img, u_of(i), v, COLORS[0]) or i == 7, i
        red = near_colour(img, u_of(i), v, (220, 0, 0), radius=1)
        assert red == (i == 7), i  # a red dot on the diverged frame only
    # the threshold 0.08 is a dashed grey line on row 60: about half of the plot width
    row = img[60, 75:690].astype(int)
    dashed = np.all(np.abs(row - 120) <= 30, axis=-1).mean()
    assert 0.3 < dashed < 0.7, dashed


def test_a_nan_is_a_gap_and_a_lone_value_a_dot():
    y = np.array([0.0, 1.0, 2.0, np.nan, np.nan, 5.0, np.nan, np.nan, 8.0, 9.0, 10.0])
    img = line_panel(FRAMES, [("y", y)], title="gap")
    # 0..10 with step 5 ticks (raw 2.5 → 5): y0 = 0, y1 = 10
    colour = COLORS[0]
    for i in (0, 1, 2, 5, 8, 9, 10):
        assert near_colour(img, u_of(i), v_of(y[i], 0.0, 10.0), colour), i
    # nothing drawn between frame 2 and 5 or between 5 and 8, away from the points themselves
    for a, b in ((2, 5), (5, 8)):
        for u in np.arange(u_of(a) + 6, u_of(b) - 6):
            assert not colour_rows_in_column(img, u, colour).size, u


def test_nice_ticks_by_hand():
    np.testing.assert_allclose(nice_ticks(0.0, 1.0), [0.0, 0.5, 1.0])  # raw step 0.25 → 0.5
    np.testing.assert_allclose(nice_ticks(-20.0, 20.0), [-20, -10, 0, 10, 20])  # raw 10 → 10
    np.testing.assert_allclose(nice_ticks(0.0, 10.0, 8), [0, 2, 4, 6, 8, 10])  # raw 1.43 → 2
    np.testing.assert_allclose(nice_ticks(0.013, 0.1), [0.0, 0.05, 0.1])  # raw 0.022 → 0.05, floor/ceil to it
    np.testing.assert_allclose(nice_ticks(3.0, 3.0), [2.5, 3.0, 3.5])  # a flat line: ±0.5 around it
    np.testing.assert_array_equal(nice_ticks(np.nan, 1.0), [0.0])


def test_stack_panels_puts_panels_top_to_bottom():
    a, b = np.zeros((2, 4, 3), np.uint8), np.full((3, 4, 3), 9, np.uint8)
    out = stack_panels([a, b])
    assert out.shape == (5, 4, 3) and out[:2].max() == 0 and out[2:].min() == 9
