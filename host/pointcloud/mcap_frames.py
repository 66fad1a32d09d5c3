"""An MCAP file of one message per depth frame, written run by run: what the Foxglove
(:mod:`.mcap_file`) and ROS 2 (:mod:`.ros2`) point cloud exports have in common. Each frame is
a message on the topic ``/fliss/points``, logged at the frame's host time, so that a player
shows the capture frame by frame; the points are in the frame ``fliss_optical`` (x right, y
down, z forward: :mod:`.geometry`)."""

import numpy as np

from .points import POINT_DTYPE


__all__ = ["FrameMessages", "TOPIC", "FRAME_ID", "CHUNK_BYTES"]

TOPIC = "/fliss/points"
FRAME_ID = "fliss_optical"
#: The MCAP chunks' size before compression. The writer keeps an index entry of each chunk in
#: memory to the end (some 660 bytes: about 0.9 MB for a 1 GB capture's 1.3 GB of points),
#: and a chunk's own copies while it is compressed and written (a few times its size).
CHUNK_BYTES = 1 << 20


class FrameMessages:
    """Writes ``total`` points to ``path``, a message per frame: :meth:`write` each run (whole
    frames), then :meth:`close`. ``comments`` go to the file's ``fliss`` metadata record. A
    subclass names the ``profile`` and gives :meth:`channel` and :meth:`message`."""

    suffix = ".mcap"
    #: The MCAP profile (``""``: none, ``"ros2"``).
    profile = ""

    def __init__(self, path, total, comments=()):
        from mcap.writer import Writer

        self.total, self.written = total, 0
        self._file = open(path, "wb")
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES)
        self._writer.start(profile=self.profile, library="fliss")
        self._channel = self.channel(self._writer)
        self._writer.add_metadata("fliss", {str(k): line for k, line in enumerate(comments)})
        self._sequence = 0

    def channel(self, writer):
        """Register the schema and the channel of the messages with ``writer``: the channel's
        id."""
        raise NotImplementedError

    def message(self, points, nanoseconds):
        """A frame's message, as bytes: its ``points`` (of :data:`~.points.POINT_DTYPE`, maybe
        none), at the host time ``nanoseconds`` since 1970."""
        raise NotImplementedError

    def write(self, points, frame_times):
        """The points of a run of frames, and the host time of each frame of the run by its
        number (``frame_times``: frame -> seconds): a frame without points is a message with
        none (a player then shows an empty cloud for it)."""
        points = points.astype(POINT_DTYPE, copy=False)
        # The frame numbers, in order (as frame_points makes them) unless told otherwise: one
        # copy of them, and a flag a point to check the order
        frames = np.ascontiguousarray(points["frame"])
        if (frames[1:] < frames[:-1]).any():
            order = np.argsort(frames, kind="stable")
            points, frames = points[order], frames[order]
            del order
        numbers = np.fromiter(frame_times, dtype=np.int64, count=len(frame_times))
        bounds = np.searchsorted(frames, numbers, side="left")
        ends = np.searchsorted(frames, numbers, side="right")
        del frames
        for number, start, stop in zip(numbers.tolist(), bounds.tolist(), ends.tolist()):
            nanoseconds = int(round(frame_times[number] * 1e9))
            self._writer.add_message(self._channel, log_time=nanoseconds,
                                     publish_time=nanoseconds, sequence=self._sequence,
                                     data=self.message(points[start:stop], nanoseconds))
            self._sequence += 1
            self.written += stop - start

    def close(self, check=True):
        """Finish the file; ``check``: refuse a count of points other than the one announced."""
        self._writer.finish()
        self._file.close()
        if check and self.written != self.total:
            raise RuntimeError(f"{self.total} points expected, {self.written} written")
