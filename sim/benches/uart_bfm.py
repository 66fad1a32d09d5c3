"""UART driver and monitor for cocotb: bytes to and from a 1-bit serial pin, 8N1.

Both work with timers and edges rather than once per clock cycle, so a simulator spends its
time in the design, not in Python.
"""

import cocotb
from cocotb.simtime import get_sim_time
from cocotb.triggers import Edge, Event, FallingEdge, Timer


__all__ = ["UartSource", "UartSink"]


class UartSource:
    """Drives ``pin`` with 8N1 characters at ``baud``; bit edges fall on whole picoseconds of
    an exact schedule, so long bursts keep the exact rate."""

    def __init__(self, pin, baud):
        self.pin = pin
        self.bit_ps = 1e12 / baud
        self.pin.value = 1

    async def send(self, data, *, bad_stop=False):
        """Send ``data``; ``bad_stop`` sends the last character with a low stop bit."""
        start = get_sim_time("ps")
        level = 1
        bit = 0
        for index, byte in enumerate(bytes(data)):
            stop = 0 if bad_stop and index == len(data) - 1 else 1
            for value in [0] + [(byte >> i) & 1 for i in range(8)] + [stop]:
                if value != level:
                    target = start + round(bit * self.bit_ps)
                    now = get_sim_time("ps")
                    if target > now:
                        await Timer(target - now, unit="ps")
                    self.pin.value = value
                    level = value
                bit += 1
        target = start + round(bit * self.bit_ps)
        now = get_sim_time("ps")
        if target > now:
            await Timer(target - now, unit="ps")
        self.pin.value = 1
        if level == 0:  # a low stop bit: give the line a whole idle bit
            await Timer(round(self.bit_ps), unit="ps")


class UartSink:
    """Receives 8N1 characters from ``pin``: every byte goes to :attr:`received`, a character
    with a low stop bit counts in :attr:`framing_errors`."""

    def __init__(self, pin, baud):
        self.pin = pin
        self.bit_ps = 1e12 / baud
        self.received = bytearray()
        self.framing_errors = 0
        self.event = Event()
        self._task = cocotb.start_soon(self._run())

    def stop(self):
        self._task.cancel()

    async def _run(self):
        while True:
            if int(self.pin.value) == 0:
                await Edge(self.pin)
                continue
            await FallingEdge(self.pin)
            start = get_sim_time("ps")
            # Sample each bit in its middle; record the level by following the edges.
            bits = []
            for bit in range(10):
                target = start + round((bit + 0.5) * self.bit_ps)
                await Timer(target - get_sim_time("ps"), unit="ps")
                bits.append(int(self.pin.value))
            if bits[9] != 1:
                self.framing_errors += 1
            else:
                self.received.append(sum(b << i for i, b in enumerate(bits[1:9])))
            self.event.set()
