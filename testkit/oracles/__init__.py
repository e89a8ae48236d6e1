"""Numpy forms of compiled physics, written independently, that the tests check the kernels against."""
