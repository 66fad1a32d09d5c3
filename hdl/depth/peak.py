"""Peak search of the depth engine: box filter and strongest window of each pixel, a bin per
cycle."""

from amaranth.hdl import Array, Module, Mux, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..event import TIMESTAMP_BITS
from ..histogram.layout import COUNT_WIDTH


__all__ = ["MAX_FILTER", "WINDOW_BITS", "TOTAL_BITS", "PeakFinder"]


#: Widest box filter, in bins.
MAX_FILTER = 16
#: Width of a window sum (``MAX_FILTER`` counts) and of a pixel's total (8192 counts).
WINDOW_BITS = COUNT_WIDTH + (MAX_FILTER - 1).bit_length()
TOTAL_BITS = COUNT_WIDTH + TIMESTAMP_BITS


class PeakFinder(wiring.Component):
    """Box filter and strongest window of each pixel of a histogram readout.

    Takes a bin in any cycle (``valid``), with its index in the pixel (``bin``, from 0),
    ``pixel_last`` on the pixel's last bin and the filter width ``width`` (1 to
    :data:`MAX_FILTER`, at most the pixel's bins; constant over a pixel). Window ``k`` sums bins
    ``k - W + 1 … k`` of the pixel (``k >= W - 1``). A five-stage pipeline: the bin in; the
    count leaving the window (a 15-deep delay line with a registered tap); their difference; the
    running window sum and total; the comparison with the best window so far, which keeps the
    first of equal sums, the sums of the windows before and after it, and whether they exist.
    ``width`` is taken a cycle after the bin, so it may be set in the cycle of a frame's first
    bin.

    Members
    -------
    valid : In(1)
    count : In(16)
    bin : In(13)
    pixel_last : In(1)
    frame_last : In(1)
        The pixel's last bin is the frame's last.
    width : In(range(17))
    done : Out(1)
        High for one cycle when the pixel's results below are complete (five cycles after its
        last bin); they hold until the next pixel's bins reach them.
    best : Out(WINDOW_BITS)
        The largest window sum ``F``; ``best_bin`` its window's last bin ``k``.
    best_bin : Out(13)
    left, right : Out(WINDOW_BITS)
        Sums of windows ``k - 1`` and ``k + 1``, valid with ``has_left`` and ``has_right``.
    has_left, has_right : Out(1)
    total : Out(TOTAL_BITS)
        The pixel's total count ``S``.
    last : Out(1)
        The pixel was the frame's last.
    """

    def __init__(self):
        super().__init__({
            "valid":      In(1),
            "count":      In(COUNT_WIDTH),
            "bin":        In(TIMESTAMP_BITS),
            "pixel_last": In(1),
            "frame_last": In(1),
            "width":      In(range(MAX_FILTER + 1)),
            "done":       Out(1),
            "best":       Out(WINDOW_BITS),
            "best_bin":   Out(TIMESTAMP_BITS),
            "left":       Out(WINDOW_BITS),
            "right":      Out(WINDOW_BITS),
            "has_left":   Out(1),
            "has_right":  Out(1),
            "total":      Out(TOTAL_BITS),
            "last":       Out(1),
        })

    def elaborate(self, platform):
        m = Module()

        # Stage 0: the bin, registered (``width`` may be set in the cycle of the first bin)
        v0 = Signal()
        count0 = Signal(COUNT_WIDTH)
        bin0 = Signal(TIMESTAMP_BITS)
        plast0 = Signal()
        flast0 = Signal()
        m.d.sync += v0.eq(self.valid)
        with m.If(self.valid):
            m.d.sync += [
                count0.eq(self.count),
                bin0.eq(self.bin),
                plast0.eq(self.pixel_last),
                flast0.eq(self.frame_last),
            ]

        # Stage 1: the count in, the count leaving the window (of bin - W, from a delay line of
        # the counts before: delay[j] holds the count of bin - 2 - j before the shift) and
        # whether it is in the same pixel. The delay line's tap is registered: its one cycle of
        # lag after ``width`` changes falls on the frame's first bin, which takes nothing out.
        v1 = Signal()
        count1 = Signal(COUNT_WIDTH)
        leaving1 = Signal(COUNT_WIDTH)
        inside1 = Signal()
        first1 = Signal()
        window1 = Signal()
        first_window1 = Signal()
        plast1 = Signal()
        flast1 = Signal()
        bin1 = Signal(TIMESTAMP_BITS)
        delay = Array(Signal(COUNT_WIDTH, name=f"delay{j}") for j in range(MAX_FILTER - 1))
        tap = Signal(range(MAX_FILTER - 1))
        tap_count = Signal()                            # W = 1: the previous count leaves
        m.d.sync += [
            tap.eq(self.width - 2),
            tap_count.eq(self.width == 1),
            v1.eq(v0),
        ]
        with m.If(v0):
            m.d.sync += [
                count1.eq(count0),
                leaving1.eq(Mux(tap_count, count1, delay[tap])),
                delay[0].eq(count1),
                *(delay[j].eq(delay[j - 1]) for j in range(1, MAX_FILTER - 1)),
                inside1.eq(bin0 >= self.width),
                first1.eq(bin0 == 0),
                window1.eq(bin0 + 1 >= self.width),
                first_window1.eq(bin0 + 1 == self.width),
                bin1.eq(bin0),
                plast1.eq(plast0),
                flast1.eq(flast0),
            ]

        # Stage 2: count in less count out
        v2 = Signal()
        diff2 = Signal(signed(COUNT_WIDTH + 1))
        count2 = Signal(COUNT_WIDTH)
        first2 = Signal()
        window2 = Signal()
        first_window2 = Signal()
        bin2 = Signal(TIMESTAMP_BITS)
        plast2 = Signal()
        flast2 = Signal()
        m.d.sync += [
            v2.eq(v1),
            diff2.eq(count1 - Mux(inside1, leaving1, 0)),
            count2.eq(count1),
            first2.eq(first1),
            window2.eq(window1),
            first_window2.eq(first_window1),
            bin2.eq(bin1),
            plast2.eq(plast1),
            flast2.eq(flast1),
        ]

        # Stage 3: window sum and total
        v3 = Signal()
        window_sum = Signal(self.best.shape())
        window3 = Signal()
        first_window3 = Signal()
        bin3 = Signal(TIMESTAMP_BITS)
        plast3 = Signal()
        flast3 = Signal()
        m.d.sync += [
            v3.eq(v2),
            window3.eq(window2),
            first_window3.eq(first_window2),
            bin3.eq(bin2),
            plast3.eq(plast2),
            flast3.eq(flast2),
        ]
        with m.If(v2):
            m.d.sync += [
                window_sum.eq(Mux(first2, 0, window_sum) + diff2),
                self.total.eq(Mux(first2, 0, self.total) + count2),
            ]

        # Stage 4: the best window, its neighbours
        previous = Signal.like(window_sum)
        want_right = Signal()
        with m.If(v3):
            m.d.sync += previous.eq(window_sum)
            with m.If(window3):
                with m.If(first_window3 | (window_sum > self.best)):
                    m.d.sync += [
                        self.best.eq(window_sum),
                        self.best_bin.eq(bin3),
                        self.left.eq(previous),
                        self.has_left.eq(~first_window3),
                        self.has_right.eq(0),
                        want_right.eq(1),
                    ]
                with m.Elif(want_right):
                    m.d.sync += [self.right.eq(window_sum), self.has_right.eq(1),
                                 want_right.eq(0)]
        m.d.sync += [self.done.eq(v3 & plast3), self.last.eq(flast3)]

        return m
