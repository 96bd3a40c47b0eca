"""Benchmark experiments behind ``ankle-rt bench`` (kept out of the daemon's core layer): the
daemon's own compute on replayed sensor frames (:mod:`.replay`) and the rendered-impedance
experiment (:mod:`.impedance`), walking under the gait-phase controller (:mod:`.walk`). Timing figures also travel in reference steps
(:mod:`ankle_rt.timing_reference`)."""
