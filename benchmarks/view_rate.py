"""The live view at 1 ms a histogram: does an acquisition that feeds it keep its pace, and how
often does a page in the browser redraw, with one, two or three pages open?

The model board makes 1 ms histograms slower than real time (its simulation paces itself), so
the acquisition is played here by a loop in the main thread that hands a
:class:`~fliss.host.view.feed.Feed` one 8192-bin histogram per millisecond, on time, as
``fliss capture --view`` does from its capture loop; the view's server runs on its thread in
the same process, and headless Chromium (Debian's ``chromium`` and ``chromium-driver``,
driven by Selenium) opens the pages.

Figures, per number of pages:

* frames handed to the feed against those due at 1 kHz (the acquisition keeps its pace when
  they are equal), and the time :meth:`Feed.add` takes (mean and 99th percentile, µs);
* redraws a second of the first page, counted by the browser's clock (a new count of frames
  received in the status line);
* the updates sent to each page and those it missed, not having taken the one before (the
  view's flow control), over the whole run, the pages' loading included.

Baseline: the same loop without a view (no feed, no server, no browser).

Run: .venv/bin/python benchmarks/view_rate.py [--pages 1 2 3] [--seconds 4]
"""

import argparse
import shutil
import threading
import time

import numpy as np

from fliss.host.stream import HistogramFrame
from fliss.host.view.feed import Feed, Setup
from fliss.host.view.server import ViewServer

BINS = 8192
PERIOD_S = 1e-3

COUNT = """
function find(root, cls) {
    for (const el of root.querySelectorAll('*')) {
        if (el.classList && el.classList.contains(cls)) return el;
        if (el.shadowRoot) { const inner = find(el.shadowRoot, cls); if (inner) return inner; }
    }
    return null;
}
window.flissTimes = []; window.flissSince = performance.now(); let last = null;
const status = find(document, 'fliss-status');
new MutationObserver(() => {
    const el = find(status.shadowRoot, 'n-frames'), now = el && el.textContent;
    if (now && now !== last) { last = now; window.flissTimes.push(performance.now()); }
}).observe(status.shadowRoot, {childList: true, subtree: true, characterData: true});
"""

RATE = """
const since = window.flissSince, until = since + arguments[0];
return window.flissTimes.filter(t => t > since && t <= until).length / arguments[0] * 1000;
"""


def histograms(count=64, seed=1):
    """A pool of 1 ms histograms: a victim at 26.7 ns, an aggressor at 101.7 ns, background."""
    means = np.full(BINS, 0.01)
    means[530:545] += 3
    means[2030:2045] += 1
    rng = np.random.default_rng(seed)
    return [rng.poisson(means).astype(np.uint32) for _ in range(count)]


def acquire(feed, seconds, pool):
    """Hand ``feed`` one histogram per millisecond for ``seconds``; returns (frames handed,
    frames due, add() times in s)."""
    costs = []
    start = time.monotonic()
    done = 0
    while True:
        now = time.monotonic() - start
        if now >= seconds:
            break
        due = int(now / PERIOD_S)
        while done < due:
            frame = HistogramFrame(done, 0, pool[done % len(pool)], True, 0, time.time())
            if feed is not None:
                t = time.perf_counter()
                feed.add(frame)
                costs.append(time.perf_counter() - t)
            done += 1
        time.sleep(0.0005)
    return done, int(seconds / PERIOD_S), np.array(costs)


def loop_s(seconds):
    """How long the acquisition runs: the pages' loading, the measurement and a margin."""
    return seconds + 6.0


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    options = Options()
    options.binary_location = shutil.which("chromium") or shutil.which("chromium-browser")
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--window-size=1280,1000"):
        options.add_argument(argument)
    return webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)


def measure(pages, seconds, pool):
    feed = Feed(Setup("benchmark", "histogram", PERIOD_S, 50e-12, aggressor_on=True))
    with ViewServer(feed, port=0) as server:
        driver = browser()
        try:
            result = {}

            def run():
                result["acquired"] = acquire(feed, loop_s(seconds), pool)
            loop = threading.Thread(target=run)
            loop.start()
            for index in range(pages):
                if index:
                    driver.switch_to.new_window("window")
                driver.get(server.url)
            driver.switch_to.window(driver.window_handles[0])
            time.sleep(2.0)
            driver.execute_script(COUNT)
            time.sleep(seconds + 0.2)
            redraws = driver.execute_script(RATE, seconds * 1000)
            loop.join()
            flows = server.pages()
        finally:
            driver.quit()
    done, due, costs = result["acquired"]
    return done, due, costs, redraws, flows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pages", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args(argv)
    pool = histograms()
    done, due, _ = acquire(None, loop_s(args.seconds), pool)
    print(f"baseline, no view: {done} of {due} histograms handed on time at 1 kHz")
    print(f"{'pages':>5} {'handed/due':>15} {'add() mean':>11} {'add() p99':>10} "
          f"{'page redraws/s':>15}  updates sent/missed, each page")
    for pages in args.pages:
        done, due, costs, redraws, flows = measure(pages, args.seconds, pool)
        print(f"{pages:>5} {done:>7}/{due:<7} {costs.mean() * 1e6:>8.1f} µs "
              f"{np.percentile(costs, 99) * 1e6:>7.1f} µs {redraws:>15.1f}  "
              + " ".join(f"{sent}/{missed}" for sent, missed, _ in flows))


if __name__ == "__main__":
    main()
