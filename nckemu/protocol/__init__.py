"""Pure codecs for what crosses the wire: TPKT, COTP, S7comm, NCK items, PI services, 840C user DB.

No I/O and no state; imports nothing from the rest of nckemu but the error hierarchy (``nckemu.errors``).
"""
