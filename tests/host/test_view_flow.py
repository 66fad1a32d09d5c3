"""The live view's flow control: a page that cannot keep up gets the latest frame when it is
ready again, holds at most one update on the server, and costs the capture nothing; and at 1 ms
integrations the view and the file get every histogram the board made (its own counters).

Bokeh's Python client stands in for a page: it runs no JavaScript and reads the server only
while one of its calls runs, so between calls it is a stalled page; it takes an update by doing
what the page's glue does (copy the update's number back)."""

import re
import time

import numpy as np
import pytest

pytest.importorskip("bokeh", reason="the live view needs Bokeh (pip install 'fliss[view]')")

from bokeh.client import pull_session  # noqa: E402
from bokeh.document import Document  # noqa: E402
from bokeh.models import ColumnDataSource  # noqa: E402

import fliss  # noqa: E402
from fliss.host.fileformat import read_capture  # noqa: E402
from fliss.host.stream import HistogramFrame  # noqa: E402
from fliss.host.view.document import WINDOW, build_document  # noqa: E402
from fliss.host.view.feed import Feed, Setup  # noqa: E402
from fliss.host.view.server import ViewServer  # noqa: E402
from fliss.sim.boards.model import model_board  # noqa: E402

from test_host_cli import SCENE  # noqa: E402
from test_view import wait_for  # noqa: E402

BINS = 8192
MISSED_LINE = re.compile(r"a page that left had missed (\d+) of (\d+) updates, drawing more "
                         r"slowly than they came \(it was shown the latest frame each time\)")


def frame(number, seed=None):
    rng = np.random.default_rng(number if seed is None else seed)
    return HistogramFrame(number, 0, rng.poisson(0.5, BINS).astype(np.uint32), True, 0, 0.0)


def test_a_page_behind_gets_the_latest_frame_and_the_count_of_updates_it_missed():
    feed = Feed(Setup("test", "histogram", 1e-3, 50e-12))
    doc, lines = Document(), []
    flow = build_document(doc, feed, 0.05, notify=lines.append)
    update, = (callback.callback for callback in doc.session_callbacks)
    status = doc.select_one({"css_classes": ["fliss-status"]})
    curve = next(source for source in doc.select({"type": ColumnDataSource})
                 if "positive" in source.data)

    def take():                             # what the page's glue does with an update
        flow.taken.tags = list(flow.sent.tags)

    frames = [frame(n) for n in range(12)]
    feed.add(frames[0])
    update()
    take()
    sent = 1
    while not flow.behind:                  # the page takes nothing more: it stalls
        feed.add(frames[sent])
        update()
        sent += 1
    assert sent == flow.updates == 1 + WINDOW
    for f in frames[sent:]:
        feed.add(f)
        update()
    update()                                # nothing new: no update missed
    missed = len(frames) - sent
    assert (flow.updates, flow.missed) == (sent, missed)
    assert f"showing frame <span class='n-frame'>{sent - 1}</span>" in status.text
    take()                                  # ready again: an update at once, not at the
    assert flow.updates == sent + 1         # next period: the latest frame
    update()                                # (the window has room for one more)
    assert flow.updates == sent + 2
    assert "showing frame <span class='n-frame'>11</span>" in status.text
    assert status.text.endswith(f" &middot; this page missed <span class='n-skipped'>{missed}"
                                f"</span> updates (too slow to draw them)")
    assert np.array_equal(curve.data["counts"], frames[11].counts.reshape(1024, 8).sum(axis=1))
    for callback in doc.session_destroyed_callbacks:
        callback(None)
    assert lines == [f"a page that left had missed {missed} of {sent + 2 + missed} updates, "
                     f"drawing more slowly than they came (it was shown the latest frame each "
                     f"time)"]


def test_a_page_that_takes_every_update_misses_none():
    feed = Feed(Setup("test", "histogram", 1e-3, 50e-12))
    doc = Document()
    flow = build_document(doc, feed, 0.05)
    update, = (callback.callback for callback in doc.session_callbacks)
    for n in range(5):
        feed.add(frame(n))
        update()
        flow.taken.tags = list(flow.sent.tags)
    assert (flow.updates, flow.missed) == (5, 0)
    assert "missed" not in doc.select_one({"css_classes": ["fliss-status"]}).text


def stalled_page(server):
    """A page that loads, takes the updates sent so far, then reads nothing more."""
    page = pull_session(url=server.url)
    assert wait_for(lambda: [updates for updates, _, _ in server.pages()] == [WINDOW])
    page.document.select_one({"name": "fliss-taken"}).tags = [WINDOW]
    page.request_server_info()              # (runs the client until the server answers)
    assert wait_for(lambda: server.pages()[0][:1] == (2 * WINDOW,))
    return page


def pending_bytes(server):
    """Bytes the server holds for its pages' websockets, not yet written to the socket."""
    total = 0
    for session in server._tornado.get_sessions("/"):
        for connection in session._subscribed_connections:
            stream = connection._socket.ws_connection.stream
            total += stream._total_write_index - stream._total_write_done_index
    return total


def test_a_stalled_page_costs_a_1ms_capture_nothing(tmp_path):
    # The board's own counter of histograms made, against the file's rows and the view's
    # frames, with a page that stalls for the whole capture.
    path = tmp_path / "run.h5"
    lines = []
    with model_board(scene=SCENE) as model, \
            fliss.connect(model.path, timeout_s=2.0) as board:
        board.configure(integration="1ms", mode="off")
        feed = Feed(Setup.of_registers(board.port, board.client.read_registers(),
                                       board.clock_hz))
        with ViewServer(feed, port=0, notify=lines.append) as server:
            page = stalled_page(server)
            started = time.monotonic()
            result = board.capture(str(path), acquisitions=300, watch=feed)
            seconds = time.monotonic() - started
            (updates, missed, behind), = server.pages()
            pending = pending_bytes(server)
            page.close()
            # (a session is forgotten a few seconds after its page goes)
            assert wait_for(lambda: any(MISSED_LINE.fullmatch(line) for line in lines), 20)
        made = result.status_end["frames"]
        sent = model.sent_histograms(BINS, whole=True)
    capture = read_capture(path)
    # The page: the updates on the way and no more, nothing queued, every tick missed.
    assert (updates, behind) == (2 * WINDOW, True)
    assert pending < 64 * 1024
    # (at most one a tick of the capture's time; how many ticks the server's loop gets to run
    # depends on the machine's load, so the lower bound only says that misses are counted)
    ticks = seconds / server.period_s
    assert 3 <= missed <= ticks + 1
    said, = (MISSED_LINE.fullmatch(line) for line in lines if MISSED_LINE.fullmatch(line))
    assert int(said.group(1)) >= missed
    assert int(said.group(2)) == int(said.group(1)) + 2 * WINDOW
    # The board made at least the 300 histograms asked for (more come before the STOP); the
    # file holds the first 300 whole, each as the board sent it, and the view got each of them.
    assert result.complete and result.lost_histograms == 0 and made >= 300
    assert list(capture.frames) == sorted(sent)[:300] and capture.complete.all()
    for number, row in zip(capture.frames, capture.histograms):
        assert np.array_equal(row, sent[int(number)])
    status = feed.status()
    assert (status.frames, status.lost, status.incomplete) == (300, 0, 0)
    assert np.array_equal(feed.picture(summed=True).counts, capture.histograms.sum(axis=0))
    assert int(capture.histograms.sum()) == status.events
