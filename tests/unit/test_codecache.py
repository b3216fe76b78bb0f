"""The code-object cache of generated source (softplc.runtime.codecache)."""

from softplc.runtime.codecache import CACHE_MAX_CHARS, compile_code


def test_the_same_text_gives_one_code_object_that_serves_every_namespace():
    text = "def f():\n    return k\n"
    code = compile_code(text, "<t>")
    assert compile_code(text, "<t>") is code
    assert compile_code(text, "<other file>") is not code  # the file name is in the code
    one, two = {"k": 1}, {"k": 2}
    exec(code, one)
    exec(code, two)
    assert (one["f"](), two["f"]()) == (1, 2)  # functions of their own namespace


def test_a_long_text_is_compiled_each_time():
    text = "x = 0\n" * (CACHE_MAX_CHARS // 6 + 1)
    assert len(text) > CACHE_MAX_CHARS
    assert compile_code(text, "<t>") is not compile_code(text, "<t>")
