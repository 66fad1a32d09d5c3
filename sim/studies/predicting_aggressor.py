"""The predicting aggressor of the interference study: the attacker of :mod:`fliss.sim.studies.attacker`
as an aggressor kind of :mod:`fliss.sim.studies.interference`.

:func:`attack_edges` gives the victim's TDC starts of one run (from the same
:class:`~fliss.sim.scene.pulses.EdgeSchedule` the scene simulator uses, so they are the starts
the scene simulates) to an :class:`~fliss.sim.studies.attacker.Observer` with its defaults (100 ps rms
jitter, nothing missed), runs :meth:`~fliss.sim.studies.attacker.Attacker.attack` on what it recorded, and
returns the attacker's laser triggers: at the victim's effective PRF until the lock, then at each
predicted TDC start. The aggressor's pulse reaches the victim's pixel the ghost's time of flight
after each trigger.

The attacker of :mod:`fliss.sim.studies.attacker` starts its unlocked train on an observed pulse, so its
first pulses land at the ghost's delay after the victim's starts, and the train walks away from
there. Each run of the study starts the attacker afresh, so that alignment would come back with
every run; :func:`attack_edges` moves the unlocked train by ``phase_cycles`` instead (drawn per
run, uniform over one period, as the locked aggressor's offset is): before its lock the
predicting aggressor is the paper's locked aggressor at the PRF it measured.

One attack serves every predicting aggressor of a run: they all watch the same victim, and with
100 ps of jitter (a rounding error needs 6.25 ns, 62 standard deviations) and nothing missed
every observer records the same whole cycles, so every attack would return the same triggers.
N predicting aggressors are therefore N lasers fired on one set of triggers.
"""

from functools import lru_cache

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from .attacker import Attacker, Observer
from ..scene.pulses import EdgeSchedule


__all__ = ["victim_starts", "attack_edges"]


@lru_cache(maxsize=8)
def _attacker(period, grid):
    # Building the hypotheses' tables takes about half a second: once per process and schedule
    return Attacker(period, grid=grid)


def victim_starts(settings, end_cycle, *, block=4096):
    """The victim's TDC starts (clock cycles) before ``end_cycle`` and the first one after, as
    the scene simulator makes them for ``settings`` (whole cycles: no fine step)."""
    schedule = EdgeSchedule(settings, block)
    pieces, last = [], -1
    while last < end_cycle:
        edges = np.asarray(schedule(), dtype=np.int64)
        pieces.append(edges)
        last = int(edges[-1])
    starts = np.concatenate(pieces)
    return starts[:int(np.searchsorted(starts, end_cycle, side="left")) + 1]


def attack_edges(settings, end_cycle, *, phase_cycles=0, seed=None, clock_hz=DEFAULT_CLOCK_HZ):
    """The predicting attacker's triggers against a victim for one run.

    Parameters
    ----------
    settings : fliss.sim.models.scheduler.Settings
        The victim's delay settings.
    end_cycle : int
        The run lasts until this clock cycle of the victim.
    phase_cycles : int
        Delay of the unlocked train (before the first lock and after a lost one), clock cycles.
    seed : numpy.random.SeedSequence or int or None
        Seed of the observer's jitter.

    Returns
    -------
    edges : numpy.ndarray
        The triggers in the victim's clock cycles.
    locked_after : int or None
        Observed pulses until the first lock, ``None`` if it never locked.
    """
    starts = victim_starts(settings, end_cycle)
    times, _ = Observer(clock_hz=clock_hz, seed=seed).observe(starts)
    result = _attacker(int(settings.period), bool(settings.grid)).attack(times)
    edges = result.edges
    if phase_cycles and len(edges):
        # The spans of the locks, as Attacker._edges cut them: (lock cycle, end cycle)
        cycles = np.rint(times * clock_hz).astype(np.int64)
        inside = np.zeros(len(edges), dtype=bool)
        spans = [(cycles[lock.observation],
                  cycles[lock.lost] if lock.lost is not None else cycles[-1] + 1)
                 for lock in result.locks]
        for begin, end in spans:
            inside |= (edges > begin) & (edges < end)
        train = edges[~inside] + int(phase_cycles)
        for begin, end in spans:
            train = train[~((train > begin) & (train < end))]
        edges = np.unique(np.concatenate((train, edges[inside])))
    return edges, result.locked_after
