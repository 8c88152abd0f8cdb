"""Recordings: what a machine logged, read and written in the project's columns.

Owns the recording (CSV, Parquet, several runs), the map that reads foreign files (workbooks, other
units and names), sensor glitches, and the ``nckemu recording`` commands. It knows nothing of models
or discovery: it may import ``nckemu.thermal.stats`` and nothing else of thermal/.
"""
