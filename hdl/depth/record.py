"""The arithmetic of the depth engine: a pixel's record from its peak search."""

from amaranth.hdl import Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .peak import MAX_FILTER, TOTAL_BITS, WINDOW_BITS
from ..divider import SerialDivider
from ..event import TIMESTAMP_BITS
from ..protocol import DepthRecord, DEPTH_FRACTION_BITS, DEPTH_BACKGROUND_FRACTION_BITS


__all__ = ["QUOTIENT_BITS", "RecordMaker"]


#: Quotient bits of the divisions: heights and backgrounds (in 1/16) are below 2**20.
QUOTIENT_BITS = WINDOW_BITS


class RecordMaker(wiring.Component):
    """A pixel's :class:`~fliss.hdl.protocol.DepthRecord` from the results of a
    :class:`~fliss.hdl.depth.peak.PeakFinder` (``docs/depth.md``).

    With ``R = S - F`` and ``D = N - W``: ``W R`` by ``W`` additions, then on one
    :class:`~fliss.hdl.divider.SerialDivider` the height ``F - ceil(W R / D)`` (at least 0),
    the background ``floor(16 R / D)`` (saturating) and the parabola's vertex
    ``trunc(8 (a - b) / (a + b))`` in 1/16 bin: ``W + 3 (QUOTIENT_BITS + 1) + 2`` cycles from
    ``start`` to ``done``. ``D = 0`` gives a background of 0 and a height of ``F``.

    Members
    -------
    start : In(1)
        Take the inputs below and begin.
    best, best_bin, left, right, has_left, has_right, total : In
        The pixel's peak search (as :class:`~fliss.hdl.depth.peak.PeakFinder` gives them).
    width : In(range(17))
        ``W``, the filter width used.
    bins : In(14)
        ``N``, the pixel's bins.
    threshold : In(16)
        Least height for ``detected``.
    done : Out(1)
        High for one cycle when ``record`` is ready; it holds until the next ``start``.
    record : Out(DepthRecord)
    """

    def __init__(self):
        super().__init__({
            "start":     In(1),
            "best":      In(WINDOW_BITS),
            "best_bin":  In(TIMESTAMP_BITS),
            "left":      In(WINDOW_BITS),
            "right":     In(WINDOW_BITS),
            "has_left":  In(1),
            "has_right": In(1),
            "total":     In(TOTAL_BITS),
            "width":     In(range(MAX_FILTER + 1)),
            "bins":      In(TIMESTAMP_BITS + 1),
            "threshold": In(16),
            "done":      Out(1),
            "record":    Out(DepthRecord),
        })

    def elaborate(self, platform):
        m = Module()

        m.submodules.divider = divider = SerialDivider(TOTAL_BITS + 4, WINDOW_BITS + 1,
                                                       QUOTIENT_BITS)
        record = self.record

        # The inputs, taken at `start`
        peak = Signal(WINDOW_BITS)                  # F
        peak_bin = Signal(TIMESTAMP_BITS)           # k
        rest = Signal(TOTAL_BITS)                   # R = S - F
        spare = Signal(TIMESTAMP_BITS + 1)          # D = N - W
        width = Signal.like(self.width)
        threshold = Signal.like(self.threshold)
        a = Signal(WINDOW_BITS)                     # F - f[k - 1]
        b = Signal(WINDOW_BITS)                     # F - f[k + 1]
        interpolate = Signal()
        centre = Signal(TIMESTAMP_BITS + DEPTH_FRACTION_BITS + 1)   # 16 (k + 1) - 8 W
        distance = Signal(WINDOW_BITS)              # |a - b|
        spread = Signal(WINDOW_BITS + 1)            # a + b
        later = Signal()                            # a > b: the peak lies after the window's centre
        product = Signal(TOTAL_BITS + 4)            # W R
        steps = Signal(range(MAX_FILTER + 1))
        height = Signal(signed(WINDOW_BITS + 2))

        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.start):
                    m.d.sync += [
                        peak.eq(self.best),
                        peak_bin.eq(self.best_bin),
                        rest.eq(self.total - self.best),
                        spare.eq(self.bins - self.width),
                        width.eq(self.width),
                        threshold.eq(self.threshold),
                        a.eq(self.best - self.left),
                        b.eq(self.best - self.right),
                        interpolate.eq(self.has_left & self.has_right),
                        product.eq(0),
                        steps.eq(self.width),
                    ]
                    m.next = "MULTIPLY"

            # W R, by W additions; the operands of the position
            with m.State("MULTIPLY"):
                m.d.sync += [
                    product.eq(product + rest),
                    steps.eq(steps - 1),
                    centre.eq(((peak_bin + 1) << DEPTH_FRACTION_BITS) -
                              (width << (DEPTH_FRACTION_BITS - 1))),
                    distance.eq(Mux(a > b, a - b, b - a)),
                    spread.eq(a + b),
                    later.eq(a > b),
                ]
                with m.If(steps == 1):
                    m.next = "HEIGHT"

            # Height: F - ceil(W R / D)
            with m.State("HEIGHT"):
                m.d.comb += [divider.start.eq(1), divider.dividend.eq(product),
                             divider.divisor.eq(spare)]
                m.next = "BACKGROUND"

            # Background: floor(16 R / D)
            with m.State("BACKGROUND"):
                with m.If(~divider.busy):
                    up = divider.remainder != 0
                    m.d.sync += height.eq(Mux(spare == 0, peak, peak - divider.quotient - up))
                    m.d.comb += [divider.start.eq(1),
                                 divider.dividend.eq(rest << DEPTH_BACKGROUND_FRACTION_BITS),
                                 divider.divisor.eq(spare)]
                    m.next = "STEP"

            # The parabola's vertex: 8 |a - b| / (a + b)
            with m.State("STEP"):
                with m.If(~divider.busy):
                    top = (1 << len(record.background)) - 1
                    m.d.sync += [
                        record.background.eq(Mux(spare == 0, 0,
                                                 Mux(divider.quotient > top, top,
                                                     divider.quotient))),
                        record.height.eq(Mux(height < 0, 0, height)),
                        record.detected.eq((height >= 0) & (height >= threshold)),
                    ]
                    m.d.comb += [divider.start.eq(1),
                                 divider.dividend.eq(distance << 3),
                                 divider.divisor.eq(spread)]
                    m.next = "POSITION"

            # Position: the window's centre, 16 (k + 1) - 8 W, plus the vertex
            with m.State("POSITION"):
                with m.If(~divider.busy):
                    position = Mux(~interpolate, centre,
                                   Mux(later, centre + divider.quotient,
                                       centre - divider.quotient))
                    m.d.sync += [record.position.eq(position), self.done.eq(1)]
                    m.next = "IDLE"

        with m.If(self.done):
            m.d.sync += self.done.eq(0)

        return m
