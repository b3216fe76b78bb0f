"""Test tiers: every test is `unit`, `integration` or `e2e` (markers in pyproject.toml).

- e2e: crosses a process or socket boundary (daemons, `softplc` subprocesses, Modbus over
  loopback TCP, mbpoll, the browser, pexpect);
- integration: several parts in one process (a machine program with its devices, the
  debugger over a PLC, the pytest plugin run by pytester);
- unit: the rest (one instruction family, one module).

A module is classified here by name; a test that asks for the `daemons` fixture is e2e
wherever it stands. A unit test that opens a socket or starts a process fails (the guard in
conftest.py), so a test cannot sit in a tier faster than it is.
"""

E2E = {
    "test_bench_smoke", "test_check_command", "test_cutting_pieces", "test_daemon",
    "test_daemon_hardening", "test_daemon_host_wait", "test_debug_repl", "test_e2e_cutting",
    "test_e2e_drawing", "test_exch", "test_first_hour", "test_host_client",
    "test_mass_tuning_daemon", "test_mass_tuning_e2e", "test_modbus", "test_modbus_slots",
    "test_program_contract", "test_runtime_attacks", "test_web_security",
    "test_web_api", "test_web_browser", "test_web_program", "test_web_program_browser",
    "test_web_views",
    "test_bench_ab",  # (the A/B runner's child processes and git)
}

INTEGRATION = {
    "test_cutting_dxf", "test_cutting_examples", "test_cutting_table", "test_debug_session",
    "test_devices", "test_device_snapshots", "test_drawing_table_program", "test_examples",
    "test_mass_tuning", "test_mass_tuning_program", "test_pytest_plugin", "test_readme",
    "test_servo_snapshots", "test_servo_table", "test_snapshots", "test_twidosuite_export",
    "test_verify", "test_verify_diff",  # (Spacer runs in a child process it can kill)
    "test_verify_time",  # (each requirement in a forked child, killed at its time)
    "test_config_readers",  # (a drum by symbol verified: the verifier's Spacer child)
    "test_web_machineview",
}

#: Single tests above their module's tier ("module::function").
E2E_TESTS = {"test_massest_tune::test_online_request_over_modbus",
             "test_massest_tune::test_online_waits_for_a_daemon_not_listening_yet"}

TIERS = ("unit", "integration", "e2e")


def tier_of(module: str, function: str, fixtures: list[str]) -> str:
    """The tier of test `function` in `module` (file stem) that uses `fixtures`."""
    if module in E2E or f"{module}::{function}" in E2E_TESTS or "daemons" in fixtures:
        return "e2e"
    if module in INTEGRATION:
        return "integration"
    return "unit"
