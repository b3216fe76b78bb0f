"""Peer comparisons for tools/bench_peers.py: pyrung, awlsim, Modbus servers, libmodbus."""
