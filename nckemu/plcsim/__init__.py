"""Running a user's STL program (awlsim) against the emulator."""
