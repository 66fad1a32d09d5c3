"""Width of a timestamp code in seconds, for each event source (register ``tdc_source``).

One table, :data:`CODE_S`, for the host's conversions of gates, histograms and files.
"""

from .event import TDC_LSB_S
from .finetdc import TAP_S, lsb_s
from .registers import TdcSource


__all__ = ["CODE_S", "code_s"]


#: Seconds per timestamp code of each source, a function of the settings (register name ->
#: value) and the clock frequency: the sensor's LSB, a clock cycle (coarse TDC), the fine TDC's
#: LSB ``50 ps / 2**fine_lsb``, and for its raw codes the nominal code width (``TAP_S``).
CODE_S = {
    TdcSource.SENSOR:   lambda values, clock_hz: TDC_LSB_S,
    TdcSource.COARSE:   lambda values, clock_hz: 1 / clock_hz,
    TdcSource.FINE:     lambda values, clock_hz: lsb_s(values.get("fine_lsb", 0)),
    TdcSource.FINE_RAW: lambda values, clock_hz: TAP_S,
}


def code_s(values, clock_hz):
    """Seconds per timestamp code with the settings ``values`` (register name -> value; a
    missing ``tdc_source`` or ``fine_lsb`` at its reset value)."""
    return CODE_S[TdcSource(values.get("tdc_source", TdcSource.SENSOR.value))](values, clock_hz)
