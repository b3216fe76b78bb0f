"""Run time: memory image, function blocks, clocks, the scan engine."""
