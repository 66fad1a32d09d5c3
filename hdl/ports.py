"""What each port of the top level (:class:`fliss.hdl.top.FlissTop`, as ``fliss generate`` writes
it) means: the last column of the ports table that ``fliss generate`` writes beside the Verilog,
and of the one in ``docs/ports.md`` (a test holds the two equal)."""


__all__ = ["CLOCK_PORTS", "PORT_MEANINGS"]


#: The ports Verilog conversion adds for the ``sync`` domain, before the component's own.
CLOCK_PORTS = (("clk", "in", 1), ("rst", "in", 1))

#: Port name -> its meaning, one line of Markdown.
PORT_MEANINGS = {
    "clk": "system clock, at the frequency given to `fliss generate`",
    "rst": "synchronous reset, active high",
    "uart_rx": "serial data from the host, 8N1, idle high (synchronised inside)",
    "uart_tx": "serial data to the host, 8N1, idle high",
    "laser": "victim laser trigger: high for `pulse_width` cycles per pulse",
    "tdc_start": "TDC start strobe, one cycle, in the cycle of the laser's rising edge",
    "aggressor_laser": "aggressor laser trigger",
    "sensor_valid": "sensor event strobe, asynchronous: high and low for at least 2 cycles each",
    "sensor_timestamp": "sensor timestamp (50 ps codes), stable from before `sensor_valid` rises "
                        "until 3 cycles after",
    "sensor_address": "pixel address, timed as `sensor_timestamp`",
    "sensor_collision": "collision flag, timed as `sensor_timestamp`",
    "photon_hit": "photon detector pulse for the built-in coarse TDC and, in a build with it, the "
                  "fine TDC ([finetdc.md](finetdc.md)), asynchronous",
    "running": "acquisition running (for an LED)",
    "laser_pad": "with the fine TDC: the pad of `laser` read back (a bidirectional pad, its "
                 "output always enabled), for its internal loopback",
    "aggressor_laser_pad": "with the fine TDC: the pad of `aggressor_laser` read back, as "
                           "`laser_pad`",
}
