"""Low-pass filtering and time derivatives of sampled signals, accurate at the ends.

Every function works on arrays ``(F, ...)`` sampled at ``fps`` along axis 0 and treats
all other axes as independent channels (one vectorised call, never a loop over frames).

Methods (:class:`FilterSpec`):

* ``"butter"`` (default): zero-lag Butterworth low-pass — a 2nd-order filter run forward
  and backward (``scipy.signal.sosfiltfilt``), i.e. 4th order overall. The design
  frequency is raised so the *combined* two-pass filter is −3 dB at ``cutoff``
  (Winter 2009, §3.4.4.3). Before filtering each end is extended by odd reflection
  about the end sample with the even-order terms of a local degree-4 polynomial fit
  restored, so position, velocity and acceleration continue smoothly across the end
  (plain reflection would force the acceleration towards zero there). Derivatives of the filtered signal are then taken
  with the five-point stencil below.
* ``"savgol"``: Savitzky–Golay smoothing and differentiation (local polynomial of
  ``polyorder``, ``scipy.signal.savgol_filter``); its window is the shortest odd length
  whose −3 dB frequency is at or below ``cutoff`` (computed from the filter's own
  frequency response). The ends are extended exactly as for ``"butter"`` (a plain
  end-window fit, SciPy's ``mode="interp"``, gives 5-10x larger end errors in the
  acceleration).
* ``"none"``: no smoothing; derivatives of the raw samples by the five-point stencil
  (4th-order accurate; at the ends the degree-4 polynomial through the first/last five
  samples is differentiated).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

FILTER_METHODS = ("butter", "savgol", "none")
DEFAULT_CUTOFF_HZ = 6.0
#: Lowest cutoff accepted (Hz): below it a low-pass removes the movement itself (a stride
#: lasts ~1 s), and the zero-lag filter's end padding grows as fps / cutoff (0.01 Hz took
#: 530 MB for a 524-frame walk; 1e-9 Hz asked numpy for 2.6 TiB).
MIN_CUTOFF_HZ = 0.1


@dataclass(frozen=True)
class FilterSpec:
    """How signals are smoothed before differentiation.

    Attributes:
        method: ``"butter"``, ``"savgol"`` or ``"none"``.
        cutoff: −3 dB frequency in Hz of the whole (zero-lag) filter.
        order: Butterworth order of one pass (the zero-lag filter has twice this).
        polyorder: Savitzky–Golay polynomial degree.
    """

    method: str = "butter"
    cutoff: float = DEFAULT_CUTOFF_HZ
    order: int = 2
    polyorder: int = 4

    def check(self, fps: float) -> FilterSpec:
        """Return self after checking the options against the sampling rate.

        Raises:
            ValueError: unknown method, or a cutoff not between 0 and the Nyquist frequency.
        """
        if self.method not in FILTER_METHODS:
            raise ValueError(f"unknown filter {self.method!r}: use one of {', '.join(FILTER_METHODS)}")
        if self.method != "none":
            nyquist = 0.5 * fps
            if not (np.isfinite(self.cutoff) and MIN_CUTOFF_HZ <= self.cutoff < nyquist):
                raise ValueError(f"--cutoff {self.cutoff:g} Hz must be at least {MIN_CUTOFF_HZ:g} Hz and below the "
                                 f"Nyquist frequency {nyquist:g} Hz of this {fps:g} fps motion")
        if self.order < 1 or not 1 <= self.polyorder <= 6:
            raise ValueError("filter order must be >= 1 and polyorder between 1 and 6")
        return self

    def describe(self, fps: float) -> dict:
        """JSON-ready description (what a report needs to reproduce the numbers)."""
        out: dict = {"method": self.method}
        if self.method == "butter":
            out.update(cutoff_hz=self.cutoff, order=2 * self.order, zero_lag=True,
                       end_padding="odd reflection + even terms of a degree-4 fit",
                       derivative="five-point stencil")
        elif self.method == "savgol":
            out.update(cutoff_hz=self.cutoff, polyorder=self.polyorder,
                       window_frames=savgol_window(self.cutoff, fps, self.polyorder))
        else:
            out.update(derivative="five-point stencil")
        return out


def _odd_at_least(n: int) -> int:
    return n if n % 2 else n + 1


@lru_cache(maxsize=64)
def savgol_window(cutoff: float, fps: float, polyorder: int, max_window: int = 4001) -> int:
    """Shortest odd Savitzky–Golay window whose −3 dB frequency is ≤ ``cutoff`` Hz."""
    from scipy.signal import freqz, savgol_coeffs

    window = _odd_at_least(polyorder + 1)
    target = cutoff / fps  # cycles per sample
    freqs = np.linspace(0.0, 0.5, 2049)
    while window < max_window:
        _, response = freqz(savgol_coeffs(window, polyorder), worN=2 * np.pi * freqs)
        below = np.flatnonzero(np.abs(response) < 1.0 / np.sqrt(2.0))
        if below.size and freqs[below[0]] <= target:
            return window
        window += 2
    return window


def _stencil(n_frames: int) -> tuple[int, int]:
    """(window, polyorder) of the unsmoothed derivative for a signal of ``n_frames``."""
    if n_frames >= 5:
        return 5, 4
    if n_frames >= 3:
        return 3, 2
    return 0, 0


def derivatives(x: np.ndarray, fps: float, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of ``x`` along ``axis`` without smoothing.

    Five-point stencil (the derivative of the degree-4 polynomial through five samples,
    centred inside, first/last five samples at the ends); three points for 3–4 frames;
    a constant slope for 2 frames; zeros for one frame.
    """
    from scipy.signal import savgol_filter

    x = np.asarray(x, dtype=np.float64)
    n = x.shape[axis]
    window, poly = _stencil(n)
    dt = 1.0 / fps
    if window == 0:
        if n == 2:
            slope = np.diff(x, axis=axis) / dt
            return np.broadcast_to(slope, x.shape).copy(), np.zeros_like(x)
        return np.zeros_like(x), np.zeros_like(x)
    d1 = savgol_filter(x, window, poly, deriv=1, delta=dt, axis=axis, mode="interp")
    d2 = savgol_filter(x, window, poly, deriv=2, delta=dt, axis=axis, mode="interp")
    return d1, d2


def _pad_length(n_frames: int, fps: float, cutoff: float) -> tuple[int, int]:
    """(pad, fit) sample counts for the end extension of a Butterworth filter.

    ``pad`` covers three periods of the cutoff (where the filter's response has died
    out); ``fit`` is one period (at least 6 samples, at most the signal).
    """
    period = fps / cutoff  # samples per cutoff period
    pad = int(round(3 * period)) + 1
    fit = min(max(6, int(round(period))), n_frames)
    return pad, fit


def _extend(x: np.ndarray, pad: int, fit: int) -> np.ndarray:
    """Extend ``x (C, F)`` (time last) by ``pad`` samples at each end.

    Odd reflection about the end sample (``2 x(0) − x(k)``) continues value, slope and
    every odd-order term exactly but flips the even ones (acceleration, snap); the even
    part of a degree-4 polynomial fitted to the first ``fit`` samples puts them back:
    ``x(−k) ≈ 2 x(0) − x(k) + P(−k) + P(k) − 2 P(0)``.
    """
    degree = min(4, fit - 2) if fit >= 4 else fit - 1
    t = np.arange(fit, dtype=np.float64)
    solve = np.linalg.pinv(np.vander(t, degree + 1))  # (d+1, fit)
    k = np.arange(pad, 0, -1, dtype=np.float64)
    even = np.vander(-k, degree + 1) + np.vander(k, degree + 1)
    even[:, -1] -= 2.0  # - 2 P(0)
    correction = even @ solve  # (pad, fit): maps the first `fit` samples to the even terms
    mirror = np.minimum(np.arange(pad, 0, -1), x.shape[-1] - 1)

    def ahead(block: np.ndarray) -> np.ndarray:
        """Samples at t = -pad..-1 before ``block[..., 0]`` (block runs forward in time)."""
        return 2.0 * block[..., :1] - block[..., mirror] + block[..., :fit] @ correction.T

    head = ahead(x)
    tail = ahead(x[..., ::-1])[..., ::-1]
    return np.concatenate([head, x, tail], axis=-1)


def butter_lowpass(x: np.ndarray, fps: float, cutoff: float, order: int = 2, axis: int = 0) -> np.ndarray:
    """Zero-lag Butterworth low-pass of ``x`` along ``axis``, −3 dB at ``cutoff`` Hz overall."""
    from scipy.signal import butter, sosfiltfilt

    x = np.asarray(x, dtype=np.float64)
    n = x.shape[axis]
    if n < 3:
        return x.copy()
    last = np.moveaxis(x, axis, -1)
    flat = np.ascontiguousarray(last).reshape(-1, n)
    # two passes: |H|^2 of one pass must be 1/sqrt(2) at the cutoff
    correction = (np.sqrt(2.0) - 1.0) ** (1.0 / (2 * order))
    design = min(cutoff / correction, 0.499 * fps)
    sos = butter(order, design, btype="low", fs=fps, output="sos")
    pad, fit = _pad_length(n, fps, cutoff)
    filtered = sosfiltfilt(sos, _extend(flat, pad, fit), axis=-1, padtype=None)
    return np.moveaxis(filtered[:, pad:pad + n].reshape(last.shape), -1, axis)


def smooth_derivatives(x: np.ndarray, fps: float, spec: FilterSpec = FilterSpec(),
                       axis: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(smoothed, first derivative, second derivative)`` of ``x`` along ``axis`` (time).

    Derivatives are per second. See the module docstring for the methods. Shapes equal
    ``x``'s. Time as the last, contiguous axis is about twice as fast as axis 0.
    """
    from scipy.signal import savgol_filter

    x = np.asarray(x, dtype=np.float64)
    spec.check(fps)
    if spec.method == "savgol":
        window = savgol_window(spec.cutoff, fps, spec.polyorder)
        n = x.shape[axis]
        if window <= n:
            last = np.moveaxis(x, axis, -1)
            flat = np.ascontiguousarray(last).reshape(-1, n)
            pad, fit = _pad_length(n, fps, spec.cutoff)
            pad = max(pad, window // 2 + 1)
            extended = _extend(flat, pad, fit)
            kw = dict(window_length=window, polyorder=spec.polyorder, delta=1.0 / fps, axis=-1, mode="interp")
            return tuple(np.moveaxis(savgol_filter(extended, deriv=d, **kw)[:, pad:pad + n].reshape(last.shape), -1,
                                     axis) for d in (0, 1, 2))
        smoothed = x  # shorter than one window: fall back to the plain stencil
    elif spec.method == "butter":
        smoothed = butter_lowpass(x, fps, spec.cutoff, spec.order, axis=axis)
    else:
        smoothed = x
    d1, d2 = derivatives(smoothed, fps, axis=axis)
    return smoothed, d1, d2
