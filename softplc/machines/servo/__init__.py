"""The servo XY table of seed 002: its host client, the PMACTuningPro moves and `softplc servo`."""
