"""emulator/nck."""
