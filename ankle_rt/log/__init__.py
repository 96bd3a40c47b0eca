"""The daemon's run log: one fixed-size binary record per control cycle (see docs/log-format.md).

:mod:`.record` defines the record layout, :mod:`.writer` the preallocated ring and the writer
thread, :mod:`.reader` reads a log back (tolerating a torn last record) and exports it.
"""
