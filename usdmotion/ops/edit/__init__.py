"""MotionLab-style motion editing (after Bruderlin & Williams 1995), ``Motion -> Motion``.

Every operation is a pure function on arrays (no per-frame Python loops); most act on
the whole body or on one joint (``joint=``) and optionally its subtree (``subtree=True``).

=============  ===========================================================
``equalize``   band gains of the à-trous pyramid (presets in ``PRESETS``)
``reorient``   rigid new heading / start position about the up axis
``displace``   displacement map from keyed pose changes
``layer``      additive curve on one channel
``blend``      blend two motions (curve, timing, peak/DTW alignment)
``speed``      time-warp by a constant or keyed speed curve
``resample``   another frame rate, same duration
``cycle``      loop a range with a cross-fade, path continues
``trim``       keep frames ``[start, stop)``
=============  ===========================================================
"""

from usdmotion.ops.edit._common import EditError
from usdmotion.ops.edit.blend import blend
from usdmotion.ops.edit.cycle import cycle
from usdmotion.ops.edit.displace import displace, layer
from usdmotion.ops.edit.equalize import PRESETS, equalize
from usdmotion.ops.edit.timewarp import resample, speed, trim
from usdmotion.ops.edit.trajectory import reorient

__all__ = ["PRESETS", "EditError", "blend", "cycle", "displace", "equalize", "layer", "reorient", "resample",
           "speed", "trim"]
