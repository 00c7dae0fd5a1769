"""Simulated MiniRQuad microcontroller: robot physics, protocol endpoint, pty, fault injection."""
