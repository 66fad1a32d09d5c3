"""The rows of a framed capture file: frames stored in order, and rows of zeros for those lost."""

from .kinds import kind_of


__all__ = ["FrameRows"]


class FrameRows:
    """The frame rows of a capture: ``acquisitions`` consecutive frame numbers from the
    first one, with a row marked incomplete (zeros; nothing detected) for each that never
    arrived.

    Histograms and depth frames are numbered apart, each from reset, while the board's STATUS
    ``frames`` counts both. ``first_expected`` (STATUS ``frames`` at the start) is the first
    frame's number when the board has made frames of this readout only; a first frame that
    arrives numbered behind it shows that the board made frames of the other readout too, and
    is taken as the capture's first."""

    def __init__(self, writer, acquisitions, first_expected, configuration, mode):
        self.writer, self.acquisitions = writer, acquisitions
        self.first_expected, self.shift = first_expected, configuration["bin_shift"]
        self.configuration, self.mode = configuration, mode
        self.kind = kind_of(mode)
        self.first = None       # frame number of the first row
        self.next = None        # frame number of the next row
        self.saved = self.lost = self.incomplete = self.discarded = 0

    @property
    def done(self):
        return self.saved >= self.acquisitions

    def add(self, item):
        """Store a frame (of the capture's kind of data), after rows for the frames lost
        before it; returns the rows added."""
        if self.next is None:
            ahead = (item.frame - self.first_expected) % (1 << 32)
            self.first = self.first_expected if ahead < self.acquisitions else item.frame
            self.next = self.first
        ahead = (item.frame - self.next) % (1 << 32)
        if self.done or ahead >= 1 << 31:       # beyond the capture, or from before it
            self.discarded += 1
            return 0
        before = self.saved
        self.lose_up_to(item.frame)
        if self.done:
            self.discarded += 1
        elif self.writer.add_frame(item):
            self.saved += 1
            self.incomplete += not getattr(item, "complete", True)
            self.next = (item.frame + 1) % (1 << 32)
        else:
            self.discarded += 1
        return self.saved - before

    def lose_made(self, made):
        """Rows of zeros for the frames, of the ``made`` ones the board completed during the
        capture (STATUS ``frames`` at the end less at the start), that never arrived, up to the
        last one asked for."""
        if self.first is None:
            return
        end = (self.first + min(made, self.acquisitions)) % (1 << 32)
        if (end - self.next) % (1 << 32) < 1 << 31:     # (never back to before the next row)
            self.lose_up_to(end)

    def lose_up_to(self, frame):
        """Rows of zeros for the frames from the next one up to ``frame`` (excluded)."""
        if self.next is None:
            return
        while self.next != frame and not self.done:
            self.writer.add_frame(self.kind.blank(self.next, self.configuration),
                                  complete=False)
            self.saved += 1
            self.lost += 1
            self.next = (self.next + 1) % (1 << 32)
