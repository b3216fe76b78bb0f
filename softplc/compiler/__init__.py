"""Rungs (AST) -> resolve pass -> Python source -> callable scan functions."""

from softplc.compiler.codegen import CompiledProgram, compile_program
from softplc.compiler.resolve import Resolved, resolve

__all__ = ["CompiledProgram", "Resolved", "compile_program", "resolve"]
