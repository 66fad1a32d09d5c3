"""The imager's part of ``fliss demo``: the depth profiles of a line scene measured with FLISS
off and on, drawn beside the scene's true profile, and how many pixels each got wrong.

:func:`compare_profiles` takes the two sets of depth frames (:class:`~fliss.host.imager.results.
DepthFrames` from :meth:`~fliss.host.board.Board.acquire_depth`, a depth
:class:`~fliss.host.fileformat.Capture`, or a ``(frames, pixels)`` array of depths in metres)
and the true depth of each pixel; :func:`summary_lines` says it in a few lines and
:func:`draw_profiles` draws it.
"""

import math
from dataclasses import dataclass

import numpy as np


__all__ = ["DEFAULT_TOLERANCE_M", "FLISS_OFF", "FLISS_ON", "ProfileResult", "Comparison",
           "depth_array", "profile", "compare_profiles", "summary_lines", "draw_profiles",
           "run_on_board"]

#: How far from the truth a depth may be and still count as right, in metres.
DEFAULT_TOLERANCE_M = 0.15

#: Settings of the two runs (as :meth:`fliss.host.board.Board.configure` takes them).
FLISS_OFF = {"mode": "off"}
FLISS_ON = {"mode": "masked", "mask_width": 6}


@dataclass(frozen=True)
class ProfileResult:
    """One setting's depth profile against the truth.

    Attributes
    ----------
    depth_m : numpy.ndarray
        ``(P,)`` each pixel's median depth over the frames that detected a target (NaN if none).
    per_frame_m : numpy.ndarray
        ``(n, P)`` the depth of each pixel in each frame (NaN: nothing detected).
    wrong : numpy.ndarray
        ``(P,)`` True where the median depth is more than the tolerance from the truth.
    missing : numpy.ndarray
        ``(P,)`` True where no frame detected a target.
    wrong_frames : float
        Fraction of (frame, pixel) detections more than the tolerance from the truth.
    """
    depth_m: np.ndarray
    per_frame_m: np.ndarray
    wrong: np.ndarray
    missing: np.ndarray
    wrong_frames: float


@dataclass(frozen=True)
class Comparison:
    """FLISS off against FLISS on, with the truth, the pixel addresses and the tolerance."""
    off: ProfileResult
    on: ProfileResult
    truth_m: np.ndarray
    pixels: np.ndarray
    tolerance_m: float


def depth_array(frames) -> np.ndarray:
    """``(n, P)`` depths in metres (NaN where nothing was detected) of depth frames given as
    :class:`~fliss.host.imager.results.DepthFrames`, a depth capture, or an array."""
    if hasattr(frames, "depth") and isinstance(frames.depth, dict):
        return np.asarray(frames.depth["depth_m"], dtype=float)[frames.complete]
    values = getattr(frames, "depth_m", frames)
    values = np.asarray(values, dtype=float)
    return values.reshape(1, -1) if values.ndim == 1 else values


def profile(frames, truth_m, tolerance_m: float = DEFAULT_TOLERANCE_M) -> ProfileResult:
    """The depth profile of ``frames`` (see :func:`depth_array`) against ``truth_m`` ``(P,)``."""
    per_frame = depth_array(frames)
    truth = np.asarray(truth_m, dtype=float)
    if per_frame.shape[1:] != truth.shape:
        raise ValueError(f"depth frames of {per_frame.shape[1]} pixels against a true "
                         f"profile of {truth.size}")
    found = np.isfinite(per_frame)
    missing = ~found.any(axis=0)
    with np.errstate(all="ignore"):
        median = np.array([np.median(column[np.isfinite(column)]) if np.isfinite(column).any()
                           else math.nan for column in per_frame.T])
        wrong = ~missing & (np.abs(median - truth) > tolerance_m)
        off = found & (np.abs(per_frame - truth) > tolerance_m)
    wrong_frames = float(off.sum() / found.sum()) if found.any() else 0.0
    return ProfileResult(median, per_frame, wrong, missing, wrong_frames)


def compare_profiles(off, on, truth_m, pixels=None, *,
                     tolerance_m: float = DEFAULT_TOLERANCE_M) -> Comparison:
    """Depth frames taken with FLISS ``off`` and ``on`` against the scene's ``truth_m``
    ``(P,)``; ``pixels`` their addresses (by default those of the frames, or 0 …)."""
    truth = np.asarray(truth_m, dtype=float)
    if pixels is None:
        pixels = getattr(off, "pixels", None)
    pixels = np.arange(len(truth)) if pixels is None or not len(pixels) else np.asarray(pixels)
    return Comparison(profile(off, truth, tolerance_m), profile(on, truth, tolerance_m), truth,
                      pixels, tolerance_m)


def summary_lines(comparison: Comparison) -> list:
    """A few lines: per setting, the pixels at a wrong depth and without a target."""
    lines = []
    total = len(comparison.truth_m)
    for name, result in (("FLISS off", comparison.off), ("FLISS on", comparison.on)):
        wrong = np.flatnonzero(result.wrong)
        where = (" (pixels " + ", ".join(str(comparison.pixels[i]) for i in wrong[:8])
                 + (", ..." if len(wrong) > 8 else "") + ")") if len(wrong) else ""
        lines.append(f"{name}: {len(wrong)} of {total} pixels at a wrong depth (more than "
                     f"{comparison.tolerance_m:g} m from the scene){where}, "
                     f"{int(result.missing.sum())} without a target; "
                     f"{result.wrong_frames:.0%} of the detections in single frames wrong")
    return lines


def draw_profiles(comparison: Comparison, output: str, *, title: str = "") -> None:
    """Draw the two depth profiles beside each other, each with the truth, into ``output``;
    one legend below both."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from ..plotting import legend_below

    figure, axes = plt.subplots(1, 2, figsize=(11, 4.6), sharey=True, layout="constrained")
    pixels = comparison.pixels
    top = np.nanmax(np.concatenate([comparison.truth_m, comparison.off.per_frame_m.ravel(),
                                    comparison.on.per_frame_m.ravel()]))
    for axis, name, result in ((axes[0], "FLISS off", comparison.off),
                               (axes[1], "FLISS on", comparison.on)):
        frames = len(result.per_frame_m)
        for index, row in enumerate(result.per_frame_m):
            axis.plot(pixels, row, ".", color="0.6", markersize=3,
                      label=f"single frames ({frames})" if index == 0 else None)
        axis.step(pixels, comparison.truth_m, where="mid", color="k", linewidth=1.2,
                  label="scene")
        axis.plot(pixels, result.depth_m, "o", color="tab:blue", markersize=4,
                  label="measured (median over the frames)")
        axis.plot(pixels[result.wrong], result.depth_m[result.wrong], "x", color="tab:red",
                  markersize=9, label=f"wrong depth (more than {comparison.tolerance_m:g} m "
                                      f"from the scene)")
        axis.set_title(f"{name}: {int(result.wrong.sum())} pixels at a wrong depth "
                       f"({result.wrong_frames:.0%} of single-frame depths)", fontsize="small")
        axis.set_xlabel("pixel address")
        axis.set_ylim(0, (top if np.isfinite(top) else 1.0) * 1.1)
    axes[0].set_ylabel("depth (m)")
    legend_below(figure, *axes[0].get_legend_handles_labels())
    if title:
        figure.suptitle(title)
    try:
        figure.savefig(output, dpi=110)
    finally:
        plt.close(figure)


def run_on_board(board, truth_m, output: str, *, frames: int = 20, settings=None,
                 off=FLISS_OFF, on=FLISS_ON, tolerance_m: float = DEFAULT_TOLERANCE_M,
                 title: str = ""):
    """The whole comparison on ``board`` (a :class:`~fliss.host.board.Board`, the virtual one
    in ``fliss demo``): ``settings`` first (the pixel split, the aggressor, ...), then
    ``frames`` depth frames with ``off`` and with ``on``, drawn into ``output`` beside
    ``truth_m`` ``(P,)``. Returns the :class:`Comparison`; :func:`summary_lines` says it."""
    if settings:
        board.configure(settings)
    board.configure(off)
    depth_off = board.acquire_depth(frames)
    board.configure(on)
    depth_on = board.acquire_depth(frames)
    comparison = compare_profiles(depth_off, depth_on, truth_m, depth_off.pixels,
                                  tolerance_m=tolerance_m)
    draw_profiles(comparison, output, title=title)
    return comparison
