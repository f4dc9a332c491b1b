"""Where JAX runs for retargeting: the device it picked and its persistent compilation cache."""

from __future__ import annotations

import os
from pathlib import Path


def device_description() -> str:
    """The device JAX computes on, e.g. ``"cpu"`` or ``"gpu (NVIDIA H100)"``."""
    import jax

    device = jax.devices()[0]
    kind = getattr(device, "device_kind", "")
    return device.platform + (f" ({kind})" if kind and kind.lower() != device.platform else "")


def enable_compilation_cache() -> str | None:
    """Turn on JAX's persistent compilation cache (for command-line runs); returns its folder.

    Folder: ``$USDMOTION_JAX_CACHE``, else ``$XDG_CACHE_HOME/usdmotion/jax`` (default
    ``~/.cache/usdmotion/jax``); ``USDMOTION_JAX_CACHE=off`` disables it. A cache folder
    the user already configured for JAX is left alone. Repeat runs on the same skeletons
    then skip most of the XLA compile time.
    """

    import jax

    setting = os.environ.get("USDMOTION_JAX_CACHE", "")
    if setting.lower() in ("off", "0", "no", "false") or jax.config.jax_compilation_cache_dir:
        return jax.config.jax_compilation_cache_dir or None
    cache_home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    folder = Path(setting) if setting else cache_home / "usdmotion" / "jax"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    return str(folder)
