"""The daemon's run log: one fixed-size binary record per control cycle (see docs/log-format.md).

:mod:`.record` defines the record layout and the CRC'd ring the loop packs into, :mod:`.header` the
twice-stored header, :mod:`.writer` the writer thread (rotation, retention), :mod:`.reader` reads a
log back (keeping every intact record, counting damaged ones), :mod:`.export` writes CSV and MCAP,
:mod:`.summary` summarises a run.
"""
