"""The live view without a browser (tests/host/test_view_browser.py has one): the feed's numbers
against scenes worked out here, the server's refusals and its count of pages (Bokeh's Python
client standing in for a browser), `fliss view` and `fliss capture --view` on the model board,
and replays of capture files."""

import math
import re
import time
import types
import urllib.request

import numpy as np
import pytest

pytest.importorskip("bokeh", reason="the live view needs Bokeh (pip install 'fliss[view]')")

from bokeh.client import pull_session  # noqa: E402
from bokeh.models import ColumnDataSource  # noqa: E402

import fliss  # noqa: E402
from fliss.hdl.registers import defaults  # noqa: E402
from fliss.host.cli import main  # noqa: E402
from fliss.host.errors import ViewError  # noqa: E402
from fliss.host.fileformat import CaptureWriter, read_capture  # noqa: E402
from fliss.host.stream import EventBatch, HistogramFrame  # noqa: E402
from fliss.host.view import feed as feed_module  # noqa: E402
from fliss.host.view.feed import Feed, Setup  # noqa: E402
from fliss.host.view.live import watch  # noqa: E402
from fliss.host.view.replay import Replay, items_of  # noqa: E402
from fliss.host.view.server import ViewServer  # noqa: E402
from fliss.protocol.events import EVENT_DTYPE  # noqa: E402
from fliss.sim.boards.model import model_board  # noqa: E402

import imager_frames as imager  # noqa: E402
from test_host_cli import SCENE  # noqa: E402

C = 299_792_458.0
LSB_S = 50e-12
BINS = 8192
SIGMA_S = 2.1e-9 / 2.3548           # the paper's 2.1 ns FWHM pulse
VICTIM_S = 2 * 4.0 / C              # a target at 4 m: 26.685 ns
AGGRESSOR_S = 101.7e-9


def mean_counts(peaks, background=0.02):
    """Mean counts per 50 ps bin: Gaussian echoes ``(tof_s, photons)`` over a background."""
    edges = np.arange(BINS + 1) * LSB_S
    means = np.full(BINS, background)
    for tof, photons in peaks:
        cdf = np.array([0.5 * (1 + math.erf((edge - tof) / (SIGMA_S * math.sqrt(2))))
                        for edge in edges])
        means += photons * np.diff(cdf)
    return means


def histogram_frames(numbers, means, seed=1, incomplete=()):
    rng = np.random.default_rng(seed)
    return [HistogramFrame(number, 0, rng.poisson(means).astype(np.uint32),
                           number not in incomplete, 0, 0.0) for number in numbers]


def setup(readout="histogram", **more):
    return Setup("test", readout, 1e-3, LSB_S, **more)


def wait_for(condition, timeout_s=10.0):
    end = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > end:
            return False
        time.sleep(0.02)
    return True


# The feed


def test_feed_shows_the_latest_frame_and_the_sum():
    numbers = [10, 11, 12, 15, 16, 17]          # 13 and 14 lost on the way
    frames = histogram_frames(numbers, mean_counts([(VICTIM_S, 300)]), incomplete=(16,))
    feed = Feed(setup())
    assert feed.picture().frames == 0 and feed.state == "waiting for the first frame"
    for frame in frames:
        feed.add(frame)
    latest = feed.picture()
    assert (latest.frame, latest.frames, latest.summed) == (17, 1, False)
    assert np.array_equal(latest.counts, frames[-1].counts)
    assert latest.total == int(frames[-1].counts.sum())
    assert latest.time_ns[:2] == pytest.approx([0.025, 0.075])       # bin centres, 50 ps
    total = np.sum([frame.counts for frame in frames], axis=0, dtype=np.int64)
    summed = feed.picture(summed=True)
    assert (summed.frames, summed.summed, summed.total) == (6, True, int(total.sum()))
    assert np.array_equal(summed.counts, total)
    victim, = summed.peaks
    assert victim.tof_ns == pytest.approx(VICTIM_S * 1e9, abs=0.2)     # a few bins
    assert victim.distance_m == pytest.approx(victim.tof_ns * 1e-9 * C / 2)
    assert victim.fwhm_ns == pytest.approx(2.1, rel=0.1)
    status = feed.status()
    assert (status.state, status.frames, status.lost, status.incomplete) == \
        ("acquiring", 6, 2, 1)
    assert status.events == int(total.sum())
    feed.clear_sum()
    more = histogram_frames([18, 19], mean_counts([(VICTIM_S, 300)]), seed=2)
    for frame in more:
        feed.add(frame)
    again = feed.picture(summed=True)
    assert again.frames == 2
    assert np.array_equal(again.counts, more[0].counts.astype(np.int64) + more[1].counts)


def test_feed_suppression_of_victim_and_aggressor():
    # The victim's echo three times the aggressor's: S = 10 log10(3) = 4.77 dB.
    means = mean_counts([(VICTIM_S, 300), (AGGRESSOR_S, 100)])
    # Knowing only that the aggressor was on, the view cannot tell whose each peak is.
    feed = Feed(setup(aggressor_on=True))
    for frame in histogram_frames(range(20), means):
        feed.add(frame)
    picture = feed.picture(summed=True)
    assert [peak.role for peak in picture.peaks] == ["unknown", "unknown"]
    assert picture.suppression_db is None
    assert picture.note.startswith("unknown: the delay settings are not known")
    # Told where the victim is, the other peak is the aggressor's.
    fliss_off = dict(defaults(imager.CLOCK_HZ), delay_mode=0, aggressor=1)
    for victim, s_db in ((VICTIM_S, 10 * math.log10(3)), (AGGRESSOR_S, -10 * math.log10(3))):
        feed = Feed(setup(aggressor_on=True, victim_s=victim, configuration=fliss_off))
        for frame in histogram_frames(range(20), means):
            feed.add(frame)
        picture = feed.picture(summed=True)
        roles = {peak.role: peak.tof_ns for peak in picture.peaks}
        assert roles["victim"] == pytest.approx(victim * 1e9, abs=0.2)
        assert picture.suppression_db == pytest.approx(s_db, abs=0.3)
        assert not picture.suppression_limited


def test_feed_imager_depth_and_intensity():
    frames = imager.histogram_frames(3)
    feed = Feed(setup("image"))
    for frame in frames:
        feed.add(frame)
    picture = feed.picture()
    assert list(picture.pixels) == list(imager.FIRST + np.arange(8))
    assert picture.depth_m == pytest.approx(imager.TRUTH_M, abs=0.05)
    assert np.array_equal(picture.intensity, frames[-1].counts.reshape(8, -1).sum(axis=1))
    assert np.array_equal(picture.counts, frames[-1].counts.reshape(8, -1).sum(axis=0))

    depths = np.tile(imager.TRUTH_M, (2, 1))
    depths[1, [0, 5]] = np.nan
    feed = Feed(setup("depth"))
    for frame in imager.depth_frames(depths, start=40):
        feed.add(frame)
    picture = feed.picture()
    assert picture.frame == 41 and picture.counts is None
    assert np.allclose(picture.depth_m, depths[1], equal_nan=True, atol=1e-6)
    assert list(picture.intensity) == [0, 40, 40, 40, 40, 0, 40, 40]


def test_feed_histograms_raw_events():
    rng = np.random.default_rng(3)
    batches = []
    for _ in range(4):
        events = np.zeros(65, EVENT_DTYPE)
        events["timestamp"] = rng.integers(0, 1 << 13, 65)
        batches.append(EventBatch(events, 0.0))
    feed = Feed(setup("raw", shift=2))
    for batch in batches:
        feed.add(batch)
    stamps = np.concatenate([batch.events["timestamp"] for batch in batches]).astype(int)
    picture = feed.picture()
    assert picture.summed is False and picture.frames == 4
    assert np.array_equal(picture.counts, np.bincount(stamps >> 2, minlength=2048))
    assert feed.status().frames == 4 and feed.status().events == 260


def test_feed_rates(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(feed_module, "time", types.SimpleNamespace(monotonic=lambda: now[0]))
    feed = Feed(setup())
    zero = dict.fromkeys(("dropped_fifo", "dropped_overrun", "dropped_histogram",
                          "dropped_gate"), 0)
    feed.add_status(zero, {"dropped_frames": 0, "missing_packets": 0})
    frames = histogram_frames(range(40), np.full(BINS, 0.01))
    for frame in frames[:20]:
        feed.add(frame)
    assert feed.status().drop_rate_hz is None       # one STATUS: no rate yet
    now[0] += 2.0
    for frame in frames[20:]:
        feed.add(frame)
    # (the gate's drops are the settings' wish, not a loss)
    feed.add_status(dict(zero, dropped_fifo=30, dropped_overrun=10, dropped_gate=999),
                    {"dropped_frames": 2, "missing_packets": 1})
    status = feed.status()
    assert status.drop_rate_hz == pytest.approx(20.0)
    assert (status.corrupt, status.missing) == (2, 1)
    assert status.frame_rate_hz == pytest.approx(10.0)        # 20 frames in 2 s
    counts = sum(int(frame.counts.sum()) for frame in frames[20:])
    assert status.count_rate_hz == pytest.approx(counts / 20 / 1e-3)


def test_feed_never_raises_into_the_acquisition(caplog):
    feed = Feed(setup())
    feed.add(HistogramFrame(0, 0, None, True, 0, 0.0))         # no counts: cannot be shown
    frames = feed.status().frames
    assert feed.state.startswith("the view stopped showing frames: ")
    assert [record.getMessage() for record in caplog.records] == [
        "the view stopped showing frames (AttributeError: 'NoneType' object has no attribute "
        "'sum'); the acquisition goes on"]
    feed.add(histogram_frames([1], np.ones(BINS))[0])          # ignored from now on
    assert feed.status().frames == frames


def test_setup_refuses_an_unknown_readout():
    with pytest.raises(ValueError, match=r"^readout 'sweep' is not one of histogram, image, "
                                         r"depth, raw$"):
        Feed(setup("sweep"))


# The page (a Bokeh document, redrawn by its callback as the server would)


def page(feed, *, takes=True):
    """The document of ``feed`` and a function that redraws it and returns its texts; the page
    takes each update (as its glue does in a browser) unless ``takes`` is false."""
    from bokeh.document import Document
    from bokeh.models import Div

    from fliss.host.view.document import build_document

    doc = Document()
    build_document(doc, feed, 0.05)
    update, = (callback.callback for callback in doc.session_callbacks)
    sent, taken = (doc.select_one({"name": name}) for name in ("fliss-sent", "fliss-taken"))

    def redraw():
        update()
        if takes:
            taken.tags = list(sent.tags)
        return {tuple(div.css_classes): div.text for div in doc.select({"type": Div})}
    return doc, redraw


def test_page_shows_frame_counts_and_peaks():
    frames = histogram_frames([3, 4], mean_counts([(VICTIM_S, 300), (AGGRESSOR_S, 100)]))
    feed = Feed(setup(aggressor_on=True, victim_s=VICTIM_S,
                      configuration=dict(defaults(imager.CLOCK_HZ), delay_mode=0, aggressor=1)))
    doc, redraw = page(feed)
    assert "showing nothing yet" in redraw()[("fliss-status",)]
    for frame in frames:
        feed.add(frame)
    texts = redraw()
    assert (f"showing frame <span class='n-frame'>4</span>, <span class='n-total'>"
            f"{int(frames[1].counts.sum())}</span> counts") in texts[("fliss-status",)]
    peaks = feed.picture().peaks
    assert f"<td style='padding: 1px 14px; text-align: right' class='tof'>" \
        f"{peaks[0].tof_ns:.3f}</td>" in texts[("fliss-peaks",)]
    assert texts[("fliss-peaks",)].startswith(
        f"<div style='margin-bottom: 4px'><b>S = <span class='n-s'>"
        f"{feed.picture().suppression_db:.2f}</span> dB [victim by --victim-tof; with the "
        f"aggressor on, the other peaks are the aggressor&#x27;s]</b>")
    curve = next(source for source in doc.select({"type": ColumnDataSource})
                 if "positive" in source.data)
    # 8192 bins drawn as 1024 sums of 8; the log curve's empty bins at half a count.
    assert np.array_equal(curve.data["counts"], frames[1].counts.reshape(1024, 8).sum(axis=1))
    assert min(curve.data["positive"]) == 0.5


def test_page_draws_the_imager_as_an_image():
    depths = np.tile(imager.TRUTH_M, (2, 1))
    depths[1, 0] = np.nan
    feed = Feed(setup("depth", shape=(2, 4)))
    doc, redraw = page(feed)
    for frame in imager.depth_frames(depths):
        feed.add(frame)
    texts = redraw()
    assert "<span class='n-detected'>7</span> of 8 pixels detect a target" in \
        texts[("fliss-status",)]
    image = next(source for source in doc.select({"type": ColumnDataSource})
                 if list(source.data) == ["image"])
    # Row 0 on top: pixels 8 to 11, then 12 to 15.
    assert np.allclose(image.data["image"][0], depths[1].reshape(2, 4), equal_nan=True,
                       atol=1e-6)


# The server


def test_server_refuses_a_port_in_use():
    with ViewServer(Feed(setup()), port=0) as first:
        with pytest.raises(ViewError) as caught:
            ViewServer(Feed(setup()), port=first.port)
    assert str(caught.value) == (f"port {first.port} on localhost is in use (another fliss "
                                 f"view?): give another with --view-port, or 0 for any free "
                                 f"port")


def test_server_counts_the_pages_open():
    lines = []
    with ViewServer(Feed(setup()), port=0, notify=lines.append) as server:
        page = urllib.request.urlopen(server.url, timeout=10).read().decode()
        assert "<title>FLISS view: test</title>" in page
        time.sleep(0.5)
        assert lines == []                      # a request for the page is not a browser
        first = pull_session(url=server.url)
        second = pull_session(url=server.url)
        assert wait_for(lambda: len(lines) == 2)
        first.close()
        assert wait_for(lambda: len(lines) == 3)
        second.close()
        assert wait_for(lambda: len(lines) == 4)
    assert lines == ["a browser opened the page (1 watching)",
                     "a browser opened the page (2 watching)",
                     "a browser left the page (1 watching)",
                     "a browser left the page (0 watching)"]


# A board


@pytest.fixture
def model():
    with model_board(scene=SCENE) as board:
        yield board


def fliss_command(capsys, *argv):
    argv = [str(part) for part in argv]
    if "--port" in argv:
        argv += ["--timeout", "2"]
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def served_at(line):
    match = re.fullmatch(r"fliss: view at http://localhost:(\d+)/ \(Ctrl-C stops\)", line)
    assert match, line
    return int(match.group(1))


def test_capture_with_a_view_loses_nothing(model, tmp_path):
    # At 1 ms a histogram, with a page open (Bokeh's client) and redrawn 20 times a second.
    path = tmp_path / "run.h5"
    with fliss.connect(model.path, timeout_s=2.0) as board:
        board.configure(integration="1ms", aggressor="on", mode="off")
        feed = Feed(Setup.of_registers(board.port, board.client.read_registers(),
                                       board.clock_hz))
        with ViewServer(feed, port=0) as server:
            page = pull_session(url=server.url)
            result = board.capture(str(path), acquisitions=150, watch=feed)
            page.close()
    capture = read_capture(path)
    sent = model.sent_histograms(BINS, whole=True)
    assert result.complete and result.lost_histograms == 0
    assert len(capture.frames) == 150 and capture.complete.all()
    for frame, row in zip(capture.frames, capture.histograms):
        assert np.array_equal(row, sent[int(frame)])
    status = feed.status()
    assert (status.state, status.frames, status.lost, status.incomplete) == \
        ("completed", 150, 0, 0)
    assert status.drop_rate_hz in (None, 0.0)       # (None: no heartbeat, ended within 1 s)
    latest = feed.picture()
    assert latest.frame == capture.frames[-1]
    assert np.array_equal(latest.counts, capture.histograms[-1])
    assert np.array_equal(feed.picture(summed=True).counts, capture.histograms.sum(axis=0))


def test_capture_command_with_view(model, tmp_path, capsys):
    path = tmp_path / "run.h5"
    status, out, err = fliss_command(capsys, "capture", "--port", model.path, "-o", path,
                                     "--integration", "2ms", "--acquisitions", 20, "--view",
                                     "--view-port", 0, "-q")
    assert (status, out) == (0, "")
    served_at(err.rstrip("\n"))
    assert len(read_capture(path).frames) == 20


def test_capture_command_with_view_board_unplugged(tmp_path, capsys):
    with model_board(scene=SCENE, kill_after=30) as model:
        status, out, err = fliss_command(capsys, "capture", "--port", model.path, "-o",
                                         tmp_path / "run.h5", "--integration", "1ms", "--view",
                                         "--view-port", 0, "-q", "--acquisitions", 1000)
    lines = err.splitlines()
    assert (status, out, len(lines)) == (1, "", 2)
    served_at(lines[0])
    assert lines[1].startswith(f"fliss: error: lost the connection to the board on "
                               f"{model.path} (")
    assert lines[1].endswith(f"; saved what was received (30 histograms) to {tmp_path}/run.h5")


def test_view_watches_a_board(model):
    with fliss.connect(model.path, timeout_s=2.0) as board:
        board.configure(integration="2ms")
        feed = Feed(Setup.of_registers(board.port, board.client.read_registers(),
                                       board.clock_hz))
        assert watch(board, feed, should_stop=lambda: feed.status().frames >= 30) == "stopped"
        assert not model.running and feed.state == "stopped"
    latest = feed.picture()
    assert np.array_equal(latest.counts, model.sent_histograms(BINS)[latest.frame])
    assert feed.status().lost == 0


def test_view_command_runs_for_a_while(model, capsys):
    status, out, err = fliss_command(capsys, "view", "--port", model.path, "--for", "1s",
                                     "--view-port", 0, "--integration", "2ms")
    assert (status, out) == (0, "")
    served_at(err.rstrip("\n"))
    assert model.starts == 1 and not model.running


def test_view_command_board_unplugged(capsys):
    with model_board(scene=SCENE, kill_after=20) as model:
        status, out, err = fliss_command(capsys, "view", "--port", model.path, "--view-port",
                                         0, "--integration", "1ms")
    lines = err.splitlines()
    assert (status, out, len(lines)) == (1, "", 2)
    served_at(lines[0])
    assert lines[1].startswith(f"fliss: error: lost the connection to the board on "
                               f"{model.path} (")


def test_view_command_port_in_use(model, capsys, tmp_path):
    path = write_histograms(tmp_path / "run.h5", 3)
    with ViewServer(Feed(setup()), port=0) as first:
        status, out, err = fliss_command(capsys, "view", path, "--view-port", first.port)
    assert (status, out) == (1, "")
    assert err == (f"fliss: error: port {first.port} on localhost is in use (another fliss "
                   f"view?): give another with --view-port, or 0 for any free port\n")


def test_view_command_refusals(capsys, monkeypatch, tmp_path):
    monkeypatch.delenv("FLISS_PORT", raising=False)
    path = write_histograms(tmp_path / "run.h5", 3)
    for argv, message in (
            ((), "give a capture FILE to replay, or --port (or FLISS_PORT) to watch a board"),
            ((path, "--integration", "1ms", "--mode", "off"),
             "--mode, --integration: settings are for a board, not for a file to replay"),
            ((path, "--speed", "0"), "--speed must be positive and finite, not 0"),
            ((path, "--speed", "inf"), "--speed must be positive and finite, not inf"),
            ((path, "--port", tmp_path / "p"),
             f"--port, --timeout: options of a board's link, and FILE ({path}) is replayed "
             f"from the file: give FILE or --port, not both"),
            ((path, "--baud", "9600"), f"--baud: an option of a board's link, and FILE ({path}) "
                                       f"is replayed from the file: give FILE or --port, not "
                                       f"both"),
            (("--port", tmp_path / "p", "--loop", "--speed", "2"),
             "--speed, --loop: options of the replay of a FILE, not of a board watched live"),
            ((path, "--for", "2"), "--for 2: give a unit: 100ms, or 2s"),
            ((tmp_path / "none.h5",), f"no such file: {tmp_path / 'none.h5'}")):
        status, out, err = fliss_command(capsys, "view", *argv, "--view-port", 0)
        assert (status, out, err) == (1, "", f"fliss: error: {message}\n")


# Replays


def write_histograms(path, n):
    frames = histogram_frames(range(5, 5 + n), mean_counts([(VICTIM_S, 50)]))
    with CaptureWriter(str(path), mode="histogram", identity=imager.identity(),
                       configuration=imager.configuration(pixel_bits=0, bin_shift=0,
                                                          first_pixel=0)) as writer:
        for frame in frames:
            writer.add_histogram(frame)
    return path


def test_replay_gives_back_the_files_frames(tmp_path):
    capture = read_capture(write_histograms(tmp_path / "run.h5", 4))
    items = list(items_of(capture))
    assert [item.frame for item in items] == [5, 6, 7, 8]
    assert all(np.array_equal(item.counts, row) for item, row in zip(items, capture.histograms))
    feed = Feed(Setup.of_capture(capture))
    assert (feed.setup.readout, feed.setup.integration_s, feed.setup.live) == \
        ("histogram", pytest.approx(imager.configuration()["integration"] / imager.CLOCK_HZ),
         False)
    replay = Replay(capture, feed, speed=100).start()
    assert replay.wait(10)
    assert feed.state == "replayed 4 frames"
    assert np.array_equal(feed.picture(summed=True).counts, capture.histograms.sum(axis=0))

    frames = imager.histogram_frames(3)
    with CaptureWriter(str(tmp_path / "image.h5"), mode="image", identity=imager.identity(),
                       configuration=imager.configuration()) as writer:
        for frame in frames:
            writer.add_frame(frame)
    items = list(items_of(read_capture(tmp_path / "image.h5")))
    assert [(item.pixel_bits, item.first_pixel) for item in items] == [(3, imager.FIRST)] * 3
    assert all(np.array_equal(item.counts, frame.counts) for item, frame in zip(items, frames))

    depths = np.tile(imager.TRUTH_M, (2, 1))
    depths[0, 2] = np.nan
    with CaptureWriter(str(tmp_path / "depth.h5"), mode="depth", identity=imager.identity(),
                       configuration=imager.configuration()) as writer:
        for frame in imager.depth_frames(depths):
            writer.add_frame(frame)
    capture = read_capture(tmp_path / "depth.h5")
    feed = Feed(Setup.of_capture(capture))
    for item in items_of(capture):
        feed.add(item)
    assert np.allclose(feed.picture().depth_m, depths[1], atol=1e-3)
    feed = Feed(Setup.of_capture(capture))
    feed.add(next(items_of(capture)))
    assert np.allclose(feed.picture().depth_m, depths[0], atol=1e-3, equal_nan=True)


def test_view_command_replays_a_file(capsys, tmp_path):
    path = write_histograms(tmp_path / "run.h5", 5)
    status, out, err = fliss_command(capsys, "view", path, "--speed", "100", "--for", "1s",
                                     "--view-port", 0)
    lines = err.splitlines()
    assert (status, out) == (0, "")
    served_at(lines[0])
    # 5 frames of 10 ms at 100 times their pace: 10 000 a second asked, 1 000 given
    assert imager.configuration()["integration"] / imager.CLOCK_HZ == pytest.approx(0.01)
    assert lines[1:] == ["fliss: view: 5 frames played 10 times slower than --speed 100 asks: "
                         "a replay hands the view at most 1000 a second",
                         "fliss: view: replayed 5 frames; the page stays until Ctrl-C or the end of "
                         "--for 1s"]
