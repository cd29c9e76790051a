r"""The shading kernel's gradient variant (``shading.kernel.Features.grad``): the same source, one
pixel per thread, compiled with its adjoint.

The forward kernel loops over ``per`` pixels per CPU thread (``for s in range(per)``: the struct
arguments are copied once per thread). Warp's reverse pass replays the body of a dynamic loop
once per iteration, but *without the dynamic loops nested in it* (the lights, the environment's
lobes, the slice lobes): inside the pixel loop every value computed after an inner loop — the
colour the lights' loop summed, then ``max(col, 0)`` — is replayed at its value before that loop,
and the adjoint of ``max`` at that stale value drops the gradient (measured: all zero where the
lights and lobes give the whole colour). At a kernel's top level the reverse pass first runs the
whole forward body, inner loops included, so every value is right.

:func:`grad_kernel` therefore compiles the kernel function with the pixel loop taken out by an
AST transform (:class:`TopLevelPixel`): the loop's body becomes the kernel's body, its ``break``
and ``continue`` become ``return``; launched with ``per = 1`` it shades pixel ``base + tid``.
The inner loops only accumulate (``+=``), whose adjoint Warp's per-iteration replay gets right
(``docs/gradients.md``; the finite-difference tests). The forward variants are compiled from the
unchanged function.
"""
from __future__ import annotations

import ast

import warp as wp

#: part of the gradient modules' names: change it when :class:`TopLevelPixel` changes (Warp's kernel
#: cache keys a module by its source, which the transform does not change)
TRANSFORM_VERSION = 1


class TopLevelPixel(ast.NodeTransformer):
    """Replace the kernel's top-level ``for s in range(per):`` by its body, with the ``break`` and
    ``continue`` that belong to it turned into ``return``."""

    def visit_FunctionDef(self, node):
        body = []
        for st in node.body:
            if (isinstance(st, ast.For) and isinstance(st.iter, ast.Call) and isinstance(st.iter.func, ast.Name)
                    and st.iter.func.id == "range" and len(st.iter.args) == 1
                    and isinstance(st.iter.args[0], ast.Name) and st.iter.args[0].id == "per"):
                body.extend(_LoopExits().visit(s) for s in st.body)
            else:
                body.append(st)
        node.body = body
        return node


class _LoopExits(ast.NodeTransformer):
    """``break``/``continue`` of the removed loop → ``return`` (those of nested loops kept)."""

    def visit_For(self, node):
        return node  # (a nested loop's own break/continue)

    def visit_While(self, node):
        return node

    def visit_Break(self, node):
        return ast.copy_location(ast.Return(value=None), node)

    def visit_Continue(self, node):
        return ast.copy_location(ast.Return(value=None), node)


def grad_kernel(func, key: str):
    """The kernel of ``func`` (a shading kernel function with arguments ``(base, per, …)``) with its
    pixel loop at the top level and its adjoint, in a module of its own (module docstring)."""
    name = f"{key}_grad{TRANSFORM_VERSION}"
    return wp.Kernel(func, key=name, module=wp.get_module(name), options={"enable_backward": True},
                     code_transformers=[TopLevelPixel()])


__all__ = ["grad_kernel", "TopLevelPixel", "TRANSFORM_VERSION"]
