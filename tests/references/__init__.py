"""Independent reference implementations written from the papers (NumPy and Numba loops).

They share no code with ``jaxkin``: the tests check the library against them and the
benchmarks measure the library beside them.
"""
