"""``fliss analyze`` and ``fliss plot`` of the imager's captures (``--readout image`` or
``depth``): the per-pixel table, as text or JSON, and the depth and intensity pictures, for all
frames together, as a grid or as an animation. :mod:`fliss.host.commands.plot` hands these
files over."""

import math
import os

import numpy as np

from ..errors import UserError
from ..plotting import literal
from ..roles import settings_text
from .analysis import as_records, capture_table, frame_depths


__all__ = ["table_lines", "table_record", "parse_shape", "plot_imager", "image_format",
           "settings_of"]


def table_lines(capture, rows):
    """The per-pixel table of ``capture`` as lines of text."""
    depth = capture.depth is not None       # (depth frames; else per-pixel histograms)
    pixels = (f"{len(capture.pixels)} pixels ({capture.pixels[0]} to {capture.pixels[-1]})"
              if len(capture.pixels) > 1 else f"pixel {capture.pixels[0]}")
    lines = [f"{capture.path}: {capture.mode} capture, {pixels}, "
             f"{int(capture.complete.sum())} complete frames of {len(capture.complete)}, bins of "
             f"{capture.bin_s * 1e12:g} ps, ended: {capture.attrs.get('end_reason', '?')}"]
    lines.append(f"  settings: {settings_of(capture)}")
    link = capture.counters.get("link", {})
    if link:
        lines.append(f"  link: {link.get('dropped_frames', 0)} corrupt frames, "
                     f"{link.get('missing_packets', 0)} missing packets")
    lines.append(f"  {'pixel':>5} {'depth (m)':>10} {'ToF (ns)':>9} {'height':>10} "
                 f"{'background':>10} {'detected':>8}" + (f" {'rate':>6}" if depth else ""))
    for row in rows:
        found = "yes" if row.detected else "no"
        lines.append(f"  {row.address:>5} {_number(row.depth_m, '.3f'):>10} "
                     f"{_number(row.tof_s * 1e9, '.3f'):>9} {_number(row.height, '.4g'):>10} "
                     f"{_number(row.background, '.4g'):>10} {found:>8}"
                     + (f" {row.detection_rate:>6.2f}" if depth else ""))
    detected = sum(row.detected for row in rows)
    lines.append(f"  {detected} of {len(rows)} pixels detected a target")
    return lines


def _number(value, form):
    return "-" if not math.isfinite(value) else format(value, form)


def table_record(capture, rows):
    """The per-pixel table of ``capture`` as a dict for JSON."""
    return {"file": capture.path, "mode": capture.mode, "bin_s": capture.bin_s,
            "settings": settings_text(capture.configuration) or None,
            "frames": int(len(capture.complete)), "complete_frames": int(capture.complete.sum()),
            "end_reason": capture.attrs.get("end_reason"), "pixels": as_records(rows)}


def parse_shape(text, pixels):
    """``(rows, columns)`` from ``"RxC"`` for ``pixels`` pixels; None for no text."""
    if text is None:
        return None
    try:
        rows, columns = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--shape {text}: give ROWSxCOLUMNS, as 8x8") from None
    if rows < 1 or columns < 1 or rows * columns != pixels:
        raise UserError(f"--shape {text}: {rows} x {columns} is not the capture's {pixels} "
                        f"pixels")
    return rows, columns


def _depths(capture):
    # Depth per frame (n, P) of the complete frames, and the summary (P,) from the table.
    keep = capture.complete
    if capture.depth is not None:
        per_frame = np.asarray(capture.depth["depth_m"])[keep]
        intensity = np.asarray(capture.depth["height"])[keep]
    else:
        counts = capture.histograms[keep]
        per_frame = frame_depths(counts, capture.bin_s, capture.shift)
        intensity = counts.sum(axis=2, dtype=np.int64)
    summary = np.array([row.depth_m for row in capture_table(capture)])
    return per_frame, intensity, summary


def plot_imager(capture, output, *, frames="summary", shape=None, title=None, quiet=False):
    """Draw the depth (a profile against the pixel, or an image with ``shape``) and the
    intensity of ``capture`` into ``output``: ``frames`` is ``"summary"`` (all frames: the
    table's depth, the summed intensity), ``"grid"`` (one panel per frame) or
    ``"animation"`` (a GIF, one picture per frame; needs pillow)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if frames == "animation":
        from matplotlib.animation import PillowWriter
        if not PillowWriter.isAvailable():
            raise UserError("--frames animation needs pillow (pip install pillow); use "
                            "--frames grid")
        if not output.lower().endswith(".gif"):
            raise UserError(f"--frames animation writes a GIF: name the output .gif, not "
                            f"{os.path.basename(output)}")
    elif output.lower().endswith(".gif"):
        raise UserError("a .gif output is an animation: add --frames animation")
    per_frame, intensity, summary = _depths(capture)
    if frames != "summary" and not len(per_frame):
        raise UserError(f"{capture.path} holds no complete frame to draw")
    shape = parse_shape(shape, len(capture.pixels))
    what = "depth (m)"
    label = literal(title or os.path.basename(capture.path))
    settings = f" ({settings_of(capture)})"
    if frames == "summary":
        figure, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        figure.suptitle(f"{label}{settings}")
        _depth_panel(axes[0], capture.pixels, summary, shape, f"{label}: depth")
        if capture.depth is None:       # (per-pixel histograms)
            _histogram_panel(figure, axes[1], capture)
        else:
            _intensity_panel(figure, axes[1], capture.pixels, intensity)
        _save(figure, output, plt)
    elif frames == "grid":
        count = len(per_frame)
        columns = min(count, 4)
        lines = math.ceil(count / columns)
        figure, axes = plt.subplots(lines, columns, figsize=(3.2 * columns, 2.6 * lines),
                                    squeeze=False, sharey=shape is None)
        for index, axis in enumerate(axes.flat):
            if index < count:
                _depth_panel(axis, capture.pixels, per_frame[index], shape,
                             f"frame {capture.frames[capture.complete][index]}",
                             limits=_limits(per_frame))
            else:
                axis.axis("off")
        figure.suptitle(f"{label}: {what} per frame{settings}")
        _save(figure, output, plt)
    else:
        from matplotlib.animation import FuncAnimation, PillowWriter
        figure, axis = plt.subplots(figsize=(6, 4))
        numbers = capture.frames[capture.complete]

        def draw(index):
            axis.clear()
            _depth_panel(axis, capture.pixels, per_frame[index], shape,
                         f"{label}: frame {numbers[index]}{settings}",
                         limits=_limits(per_frame))
        animation = FuncAnimation(figure, draw, frames=len(per_frame))
        try:
            animation.save(output, writer=PillowWriter(fps=4))
        except OSError as error:
            raise UserError(f"cannot write {output}: {error.strerror or error}") from None
        finally:
            plt.close(figure)
    if not quiet:
        print(f"wrote {output}")


def settings_of(capture):
    """Whether FLISS was on, as the capture's registers say (``"FLISS masked Wm=6, aggressor
    on"``), or that the file does not say."""
    return settings_text(capture.configuration) or "FLISS on or off: not recorded"


def _limits(depths):
    finite = np.asarray(depths)[np.isfinite(depths)]
    if not len(finite):
        return None
    return 0.0, float(finite.max()) * 1.15 + 0.1


#: What a depth panel says when no pixel detected a target (rather than empty axes).
NOTHING_DETECTED = "no pixel detected a target"


def _depth_panel(axis, pixels, depths, shape, title, limits=None):
    depths = np.asarray(depths, dtype=float)
    if not np.isfinite(depths).any():
        axis.text(0.5, 0.5, NOTHING_DETECTED, ha="center", va="center",
                  transform=axis.transAxes)
        axis.set_xticks([])
        axis.set_yticks([])
        axis.set_title(title, fontsize="small")
        return
    if shape is None:
        axis.plot(pixels, depths, "o-", markersize=3)
        axis.set_xlabel("pixel address")
        axis.set_ylabel("depth (m)")
        if limits:
            axis.set_ylim(*limits)
    else:
        # Pixel (r, c) is address first + r * columns + c; grey: no target found.
        from matplotlib import colormaps
        rows, columns = shape
        viridis = colormaps["viridis"].with_extremes(bad="0.8")
        picture = axis.imshow(depths.reshape(shape), cmap=viridis,
                              **({"vmin": limits[0], "vmax": limits[1]} if limits else {}))
        missing = "; grey: no target" if np.isnan(depths).any() else ""
        axis.figure.colorbar(picture, ax=axis, label=f"depth (m){missing}")
        for set_ticks, count in ((axis.set_xticks, columns), (axis.set_yticks, rows)):
            set_ticks(range(count) if count <= 16 else
                      range(0, count, math.ceil(count / 16)))
        axis.set_xlabel("column")
        axis.set_ylabel("row")
        title += f" (pixel {pixels[0]} + {columns} × row + column)"
    axis.set_title(title, fontsize="small")


def _histogram_panel(figure, axis, capture):
    # Intensity of each pixel against the time of flight: the summed histograms as an image.
    total = capture.histograms[capture.complete].sum(axis=0, dtype=np.int64)
    end_ns = len(total[0]) * capture.bin_s * 1e9
    picture = axis.imshow(total, aspect="auto", cmap="magma", interpolation="nearest",
                          extent=(0, end_ns, capture.pixels[-1] + 0.5, capture.pixels[0] - 0.5))
    axis.set_xlabel("time from TDC start (ns)")
    axis.set_ylabel("pixel address")
    axis.set_title("intensity (counts per bin)", fontsize="small")
    figure.colorbar(picture, ax=axis)


def _intensity_panel(figure, axis, pixels, intensity):
    picture = axis.imshow(np.asarray(intensity, dtype=float), aspect="auto", cmap="magma",
                          interpolation="nearest",
                          extent=(pixels[0] - 0.5, pixels[-1] + 0.5, len(intensity) - 0.5,
                                  -0.5))
    axis.set_xlabel("pixel address")
    axis.set_ylabel("frame")
    from matplotlib.ticker import MaxNLocator
    axis.yaxis.set_major_locator(MaxNLocator(integer=True))
    axis.set_title("peak height (counts)", fontsize="small")
    figure.colorbar(picture, ax=axis)


def image_format(output):
    """The image format of the file ``output``: its suffix, or PNG when it has none (then
    written under the name given: matplotlib would add ``.png``)."""
    return os.path.splitext(output)[1].lower().lstrip(".") or "png"


def _save(figure, output, plt):
    figure.tight_layout()
    try:
        figure.savefig(output, dpi=110, format=image_format(output))
    except OSError as error:
        raise UserError(f"cannot write {output}: {error.strerror or error}") from None
    finally:
        plt.close(figure)
