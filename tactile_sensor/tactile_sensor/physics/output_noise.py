"""The module noise a low-pass filter leaves at its output bandwidth.

The ADC delivers one sample per 1/fs with white noise sigma_sample. White noise of one-sided
density N0 [V^2/Hz] has variance N0 fs / 2 per sample, and a filter of unit DC gain passes
N0 x ENBW of it, where the equivalent noise bandwidth ENBW = integral of |H(f)|^2 over
0..inf (for fc well below fs/2, the analogue prototype's integral is the digital filter's).
So sigma(fc) = sigma_sample sqrt(2 ENBW / fs). For an n-th order Butterworth low-pass,
|H|^2 = 1 / (1 + (f/fc)^(2n)), whose integral is fc (pi / 2n) / sin(pi / 2n): 1.11 fc for
the 2nd-order filter the driver uses (``sensing.filters.Butterworth``). The paper's 9-sample
mean at 1 kHz (13 mV) corresponds to an ENBW of fs / 18 = 56 Hz.

The per-sample sigma is a parameter here (the mock ADC's, ``sim.adc_device
.white_noise_for_dynamic_range()``, is 39 mV: 13 mV x sqrt(9)); physics/ does not import
sim/.
"""

from __future__ import annotations

import math

from .errors import PhysicsError

#: The paper's module noise after its 9-sample mean [V]: its resolution 7 N / 10^(31.5/20)
#: at 0.07 V/N, and that mean's length.
PAPER_NOISE_V = 7.0 / 10.0 ** (31.5 / 20.0) * 0.07
PAPER_AVERAGE_POINTS = 9
#: Per-sample white noise that the paper's mean brings to 13 mV [V] (quantisation, 0.35 mV
#: in quadrature, is negligible).
SAMPLE_NOISE_V = PAPER_NOISE_V * math.sqrt(PAPER_AVERAGE_POINTS)
#: The firmware's ADC sample rate [Hz].
SAMPLE_RATE_HZ = 1000.0
#: The driver's torque low-pass order.
FILTER_ORDER = 2


def butterworth_enbw_hz(cutoff_hz: float, order: int = FILTER_ORDER) -> float:
    """Equivalent noise bandwidth [Hz] of an ``order``-th order Butterworth low-pass."""
    x = math.pi / (2 * order)
    return cutoff_hz * x / math.sin(x)


def noise_at_bandwidth(bandwidth_hz: float, sample_noise_v: float = SAMPLE_NOISE_V,
                       sample_rate_hz: float = SAMPLE_RATE_HZ,
                       order: int = FILTER_ORDER) -> float:
    """Output noise sigma [V] after a Butterworth low-pass with cutoff ``bandwidth_hz`` of
    white samples of sigma ``sample_noise_v`` at ``sample_rate_hz``."""
    values = (bandwidth_hz, sample_noise_v, sample_rate_hz)
    if not all(math.isfinite(v) and v > 0 for v in values) or order < 1:
        raise PhysicsError(f"The output bandwidth ({bandwidth_hz!r} Hz), sample noise "
                           f"({sample_noise_v!r} V) and sample rate ({sample_rate_hz!r} Hz) "
                           "must be positive finite numbers; fix them.")
    if bandwidth_hz >= sample_rate_hz / 2:
        raise PhysicsError(f"An output bandwidth of {bandwidth_hz:g} Hz is not below the "
                           f"Nyquist frequency of {sample_rate_hz:g} Hz sampling "
                           f"({sample_rate_hz / 2:g} Hz); choose a lower bandwidth.")
    return sample_noise_v * math.sqrt(2.0 * butterworth_enbw_hz(bandwidth_hz, order)
                                      / sample_rate_hz)
