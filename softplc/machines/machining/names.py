"""The names the `tune` command's parser shows (file names, choices): here, apart from the
tuning code, so that building the parser (`softplc --help`) imports neither numpy nor the
estimator. `tuning` and `retune` take them from here: one definition each."""

from __future__ import annotations

CAL_FILE, MEAS_FILE = "IMCal_.dta", "IMMea_.dta"  # the thesis's scope file names
SETTINGS_FILE, TEMPLATE_FILE, OUTPUT_FILE = "settings.txt", "MPSetTemp.H", "MPSet.H"
GEOMETRIES = ("settings", "macro")  # the thesis's settings file / its NC macro (§1)
TABLES = ("thesis", "machine")  # the thesis's parameter table (Fig. 3-40) / the machine's
