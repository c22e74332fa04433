"""jaxkin's runnable examples, installed with the package as ``jaxkin.examples``.

Run one with ``jaxkin demo NAME`` (``jaxkin demo --list``) or ``python examples/NAME.py``;
each writes its files into ``--output-dir`` (default: the current directory).
"""
