"""The MiniRQuad serial protocol: COBS framing, CRC-16/CCITT-FALSE, typed messages."""
