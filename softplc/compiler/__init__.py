"""Rungs (AST) -> resolve pass -> Python source -> callable scan functions."""

from .codegen import CompiledProgram, compile_program
from .resolve import Resolved, resolve

__all__ = ["CompiledProgram", "Resolved", "compile_program", "resolve"]
