"""Field captures: decode by variable name, replay against the emulator, write captures."""
