"""Mass estimation and mass-adaptive tuning of a machining-centre feed axis (seed 000,
docs/machines/machining-centre.md): the recording, settings and parameter-file
formats, the least-squares estimator (corrected), the parameter table, the thesis's wrong
formulas (`thesis`, only to show the defects) and seeded synthetic recordings (`synth`).

    from softplc.machines.machining import tune_files
    res = tune_files("settings.txt", "IMCal_.dta", "IMMea_.dta", "MPSetTemp.H", "MPSet.H")
    print(res.estimate.mass, res.estimate.uncertainty, res.row.number)
"""

from softplc.machines.machining.estimator import Estimate, estimate
from softplc.machines.machining.mpfile import MPFile
from softplc.machines.machining.params import ParameterTable, default_template
from softplc.machines.machining.recording import Channel, Recording, read_recording, write_recording
from softplc.machines.machining.settings import Settings, read_settings
from softplc.machines.machining.tuning import TuneResult, tune, tune_files

__all__ = ["Channel", "Estimate", "MPFile", "ParameterTable", "Recording", "Settings",
           "TuneResult", "default_template", "estimate", "read_recording", "read_settings",
           "tune", "tune_files", "write_recording"]
