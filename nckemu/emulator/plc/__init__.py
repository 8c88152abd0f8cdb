"""emulator/plc."""
