"""Compilation settings shared by every kernel module."""
# Fast-math without 'nnan'/'ninf': divergence checks rely on isfinite.
FASTMATH = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}
U_MIN = 1e-6  # m/s, keeps r' = r L / U finite at rest
