"""The twin's heat from recordings: `nckemu machine fit` and `machine compare` join the heat fit
(thermal/heat) and the machine file (emulator/machine) without either importing the other."""
