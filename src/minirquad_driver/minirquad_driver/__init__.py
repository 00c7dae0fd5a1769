"""MiniRQuad host driver: serial protocol, bridge node and a simulated microcontroller.

Everything inside is SI (m, s, rad, N, V, A, W, J). The wire format and its units are
specified in ``PROTOCOL.md`` next to ``setup.py``.
"""
