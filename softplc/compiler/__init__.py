"""Rungs (AST) -> Python source -> callable scan functions."""

from .codegen import CompiledProgram, compile_program

__all__ = ["CompiledProgram", "compile_program"]
