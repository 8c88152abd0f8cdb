"""The thermal model: named effects (terms), their features on a recording, the model file (TOML).

Simulation, discovery, the synthetic machine and the PLC generator all read models through it. It
may import ``nckemu.thermal.recordings`` (a feature is computed on a recording) and nothing else of
thermal/.
"""
