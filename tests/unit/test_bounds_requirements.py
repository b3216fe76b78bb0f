"""Bad requirement files and `--require-expr` texts: a coded VerifyError at line:col, never
a traceback (issue 31 item 5, issue 34 item 6)."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.errors import Code, VerifyError
from softplc.limits import MAX_EXPR_NESTING
from softplc.twido.profile import DEFAULT_PROFILE
from softplc.verify.requirements import MAX_EXPR_TREE_DEPTH, load_spec

OK = '[[requirement]]\ncheck = "never %Q0.1 AND %Q0.2"\n'
BIG = "9" * 5000


def refused(tmp_path: Path, text: str | bytes, exprs: tuple[str, ...] = ()) -> VerifyError:
    path = tmp_path / "req.toml"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    with pytest.raises(VerifyError) as e:
        load_spec(path, list(exprs), DEFAULT_PROFILE)
    return e.value


@pytest.mark.parametrize("text, line, col, words", [
    ("[environment]\nhost = 5\n" + OK, 2, 1, "environment.host: a list of strings"),
    ('[environment]\nassume = "%I0.0"\n' + OK, 2, 1, "environment.assume: a list"),
    ("environment = 5\n" + OK, 1, 1, "environment: a table expected"),
    ("requirement = 5\n", 1, 1, "an array of tables"),
    ("[[requirement]]\nname = 5\ncheck = \"never %Q0.1\"\n", 2, 1, "name must be a string"),
    ("[[requirement]]\ncheck = 5\n", 2, 1, "check: a string expected"),
    (f'[[requirement]]\ncheck = "never %MW0 = {BIG}"\n', 2, 23, "a number of 5000"),
    (f"x = {BIG}\n" + OK, 1, 5, "a number of 5000"),
    ('[[requirement]]\ncheck = "never %MW0 = 4294967296"\n', 2, 23, "32-bit range"),
    ('[[requirement]]\ncheck = "never ' + "NOT (" * 3000 + "%Q0.1" + ")" * 3000 + '"\n',
     2, 16 + 5 * (MAX_EXPR_NESTING // 2), f"nested more than {MAX_EXPR_NESTING} levels"),
    ('[[requirement]]\ncheck = "never ' + " OR ".join(["%Q0.1"] * 3000) + '"\n', 2, None,
     f"at most {MAX_EXPR_TREE_DEPTH}"),
    ("x = " + "[" * 3000 + "]" * 3000 + "\n", 1, None, "nested more than"),
    ('[[requirement]]\ncheck = "%I0.0 rising -> %Q0.1 within -5 scans"\n', 2, None,
     "within -5 scans"),
    ('[[requirement]]\nchek = "x"\n', 1, 1, "no 'check' key"),
    (OK + 'nmae = "x"\n', 3, 1, "unknown key nmae"),
    ("[environment]\nhots = []\n" + OK, 2, 1, "unknown key environment.hots"),
    ("", 0, 0, "the file is empty"),
    ("# only a comment\n", 0, 0, "no requirement to check"),
    (bytes(range(256)) * 4, 1, 1, "not a text file (a NUL"),
    (b'[[requirement]]\ncheck = "never \xff"\n', 2, 16, "not a text file: byte"),
])
def test_bad_requirement_files_are_coded_errors_at_line_col(tmp_path, text, line, col, words):
    e = refused(tmp_path, text)
    d = next(d for d in e.diagnostics if words in d.message)
    assert d.line == line and (col is None or d.column == col), str(d)
    assert d.code in (Code.SYNTAX, Code.TYPE) and len(str(e)) < 2000


def test_require_expr_nesting_is_refused_at_its_column(tmp_path):
    with pytest.raises(VerifyError) as e:
        load_spec(None, ["never " + "NOT (" * 3000 + "%Q0.1" + ")" * 3000], DEFAULT_PROFILE)
    d = e.value.diagnostics[0]  # NOT and its parenthesis: two levels each
    assert (d.file, d.line, d.column) == ("--require-expr", 1, 7 + 5 * (MAX_EXPR_NESTING // 2))


def test_limits_leave_real_requirements_alone(tmp_path):
    (tmp_path / "req.toml").write_text(
        '[environment]\nhost = ["%MW0:2"]\n[[requirement]]\nname = "n"\n'
        'check = "%I0.0 rising -> %Q0.1 within 0 scans"\n[[requirement]]\n'
        'check = "never %MD4 = #FFFFFFFF OR %MW0 = -2147483648"\n')
    spec = load_spec(tmp_path / "req.toml", ["never " + "NOT (" * 30 + "%M0" + ")" * 30],
                     DEFAULT_PROFILE)
    assert [r.kind for r in spec.requirements] == ["response", "always", "always"]
