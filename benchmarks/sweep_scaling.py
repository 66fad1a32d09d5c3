"""Scaling of the sweep engine: points per second with 1 and 2 Dask workers, same run.

Prints, measured in the same run on a ``LocalCluster`` started for each case:

* points per second with 1 and 2 workers, as processes and as threads, and the speed-up of 2
  workers over 1 (goal: at least 1.8 with 2 processes on 2 cores);
* the per-task overhead: wall time per point times the workers, less the time the point function
  itself took on the worker (its mean), and, as a baseline, the round trip of an empty task;
* the simulation time of one point.

The point function is the interference model (``fliss.sim.studies.interference:evaluate``), each point
``--frames`` frames of 1 to 4 aggressors. Cluster start-up and a first point on every worker are
left out of the rates; the best of ``--repeat`` runs is kept. On a shared machine the figures
are noisy.

Usage: ``python benchmarks/sweep_scaling.py [--points N] [--frames F] [--repeat R]``
"""

import argparse
import os
import time

from fliss.host.sweep.engine import cluster, compute
from fliss.host.sweep.spec import point_seed
from fliss.sim.studies.interference import evaluate


def model(frames):
    """The point function, its name and the points to run."""
    return evaluate, "fliss.sim.studies.interference:evaluate", \
        lambda i: {"frames": frames, "aggressors": 1 + i % 4}


def measure(workers, processes, function, points, repeat):
    """(points/s, start-up s, mean in-task s, empty-task round trip s, wall s), the best of
    ``repeat`` runs of the points on one cluster."""
    started = time.perf_counter()
    with cluster(workers, processes=processes) as client:
        startup = time.perf_counter() - started
        # Warm-up on every worker (imports, caches), not timed
        client.run(function, points[0], point_seed(0, points[0]))
        best, inside = None, []
        for _ in range(repeat):
            inside.clear()
            begun = time.perf_counter()
            compute(client, {i: (function, (p, point_seed(0, p))) for i, p in enumerate(points)},
                    lambda key, result, elapsed_s: inside.append(elapsed_s))
            wall = time.perf_counter() - begun
            if best is None or wall < best[1]:
                best = (sum(inside) / len(inside), wall)
        empty = 200
        begun = time.perf_counter()
        compute(client, {i: (int, (i,)) for i in range(empty)}, lambda *_: None)
        round_trip = (time.perf_counter() - begun) / empty * workers
    inside, wall = best
    return len(points) / wall, startup, inside, round_trip, wall


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=24)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=2, help="runs of the points, best kept")
    args = parser.parse_args()
    function, name, make = model(args.frames)
    points = [make(i) for i in range(args.points)]
    print(f"point function: {name}; {args.points} points of {args.frames} frames; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} (others' work too)")
    rates = {}
    for processes in (False, True):
        kind = "processes" if processes else "threads"
        for workers in (1, 2):
            rate, startup, inside, round_trip, wall = measure(workers, processes, function,
                                                              points, args.repeat)
            rates[kind, workers] = rate
            overhead = wall * workers / len(points) - inside
            print(f"{workers} worker {kind:9s}: {rate:7.3f} points/s  (start-up {startup:4.2f} s,"
                  f" point {inside * 1e3:7.1f} ms, overhead {overhead * 1e3:6.1f} ms/point = "
                  f"{overhead / inside * 100:5.1f} %, empty task {round_trip * 1e3:5.2f} ms)")
        print(f"  speed-up of 2 {kind} over 1: {rates[kind, 2] / rates[kind, 1]:.2f}x "
              f"(goal >= 1.8x for processes on 2 cores); load average now "
              f"{os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
