"""Mass estimation and mass-adaptive tuning of a machining-centre feed axis (seed 000,
docs/machines/machining-centre.md): the recording, settings and parameter-file
formats, the least-squares estimator (corrected), the parameter table, the thesis's wrong
formulas (`thesis`, only to show the defects) and seeded synthetic recordings (`synth`).

    from softplc.machines.machining import tune_files
    res = tune_files("settings.txt", "IMCal_.dta", "IMMea_.dta", "MPSetTemp.H", "MPSet.H")
    print(res.estimate.mass, res.estimate.uncertainty, res.row.number)
"""

from softplc.machines.lazy import lazy_exports

# name -> the submodule that defines it, imported on first use (machines/lazy.py)
_EXPORTS = {
    "Channel": "recording",
    "Estimate": "estimator",
    "MPFile": "mpfile",
    "ParameterTable": "params",
    "Recording": "recording",
    "Settings": "settings",
    "TuneResult": "tuning",
    "default_template": "params",
    "estimate": "estimator",
    "read_recording": "recording",
    "read_settings": "settings",
    "tune": "tuning",
    "tune_files": "tuning",
    "write_recording": "recording",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
