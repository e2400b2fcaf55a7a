"""LeRobot v3.0 datasets, the file format alone: :mod:`~besman.datasets.format` (what besman writes and
reads), :mod:`~besman.datasets.writer` (episodes appended, each append whole or not at all) and
:mod:`~besman.datasets.reader` (a stranger's dataset read within bounds).

Imports only :mod:`besman.core`: the tasks record episodes with it, learning reads demonstrations from it.
"""
