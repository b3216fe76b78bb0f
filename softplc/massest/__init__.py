"""Mass estimation and mass-adaptive tuning of a machining-centre feed axis (seed 000,
`../shared/reference/mass-estimation.md`): the recording, settings and parameter-file
formats, the least-squares estimator (corrected), the parameter table, the thesis's wrong
formulas (`thesis`, only to show the defects) and seeded synthetic recordings (`synth`)."""
