"""`softplc servo --plot` (servo_client.plot_tuning): titles that say what the move did."""

from __future__ import annotations

from softplc.machines.servo.client import TuningResult, plot_tuning


def _result(test: str, fe_max: float) -> TuningResult:
    # (t s, commanded, actual, fe, output): 50 ms of output, then coasting to a stop
    samples = [(k / 1000, 100 * k, 100 * k, 0.0 if test == "openloop" else 3.0 - k / 10,
                (160.0 if k < 50 else 0.0) if test == "openloop" else 0.0)
               for k in range(0, 100, 2)]
    return TuningResult(test, "X", fe_max, 9800, 0.1, samples)


def test_open_loop_plot_title_has_no_following_error(tmp_path):
    out = tmp_path / "open.svg"
    plot_tuning(_result("openloop", 0.0), str(out))
    text = out.read_text()  # matplotlib keeps each text as an SVG comment
    assert "<!-- openloop move, axis X: output 160 bits, moved +9800 counts (+23.93 mm) -->" \
        in text
    assert "FE|" not in text and "<!-- commanded -->" not in text


def test_closed_loop_plot_title_gives_the_following_error(tmp_path):
    out = tmp_path / "scurve.svg"
    plot_tuning(_result("scurve", 14.85), str(out))
    text = out.read_text()
    assert "moved +9800 counts (+23.93 mm), max |FE| 14.8 counts (36.3 µm) -->" in text
    assert "<!-- commanded -->" in text
