"""nckemu: a SINUMERIK NCK/PLC stand-in on the wire (S7comm over ISO-on-TCP)."""

__version__ = "0.1.0"
