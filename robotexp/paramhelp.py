"""`robotexp explore -m METHOD -p help`: an explorer's parameters with their types, defaults and units,
read from the plugin's signature, its declared ranges (`Explorer.parameter_bounds`) and the "Args:"
section of its class docstring (units in brackets)."""

from __future__ import annotations

import inspect
import re
from dataclasses import dataclass

__all__ = ["Parameter", "explorer_parameters", "parameters_text"]


@dataclass(frozen=True)
class Parameter:
    """One keyword parameter of an explorer."""

    name: str
    kind: str           # its annotation as written ("float", "int | None", ...)
    default: str        # repr of the default, or "required"
    doc: str            # its line of the docstring's Args (the unit first, in brackets), or ""
    range: str = ""     # its declared range ("1..100000", ">= 0"; `Explorer.parameter_bounds`), or ""


def _arg_docs(doc: str) -> dict[str, str]:
    """name -> description of the "Args:" section of a Google-style docstring (continuation lines joined)."""
    out: dict[str, str] = {}
    lines = doc.splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == "Args:")
    except StopIteration:
        return out
    indent = None
    current = None
    for line in lines[start + 1:]:
        if not line.strip():
            break
        width = len(line) - len(line.lstrip())
        if indent is None:
            indent = width
        if width < indent:
            break
        m = re.match(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*(\([^)]*\))?:\s*(.*)", line)
        if width == indent and m:
            current = m.group(1)
            out[current] = m.group(3).strip()
        elif current is not None:
            out[current] += " " + line.strip()
    return out


def explorer_parameters(method: str) -> list[Parameter]:
    """The keyword parameters of explorer plugin `method`.

    Raises:
        PluginError: unknown method.
    """
    from robotexp.explorer import Explorer
    from robotexp.registry import EXPLORERS, bounds_text, load, parameter_bounds

    cls = load(EXPLORERS, method, Explorer)
    bounds = parameter_bounds(cls)
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):          # a subclass's words win
        docs.update(_arg_docs(inspect.getdoc(klass) or ""))
    out: list[Parameter] = []
    seen: set[str] = set()
    for klass in cls.__mro__:                     # **kwargs passed on: the base class's parameters too
        if "__init__" not in vars(klass) or klass is object:
            continue
        more = False
        for p in inspect.signature(vars(klass)["__init__"]).parameters.values():
            if p.kind is inspect.Parameter.VAR_KEYWORD:
                more = True
            if p.name == "self" or p.name in seen or p.kind not in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                                                    inspect.Parameter.KEYWORD_ONLY):
                continue
            seen.add(p.name)
            ann = p.annotation
            kind = "" if ann is inspect.Parameter.empty else ann if isinstance(ann, str) else getattr(ann, "__name__",
                                                                                                      str(ann))
            default = "required" if p.default is inspect.Parameter.empty else repr(p.default)
            out.append(Parameter(p.name, kind, default, docs.get(p.name, "").split(" **kwargs")[0],
                                 bounds_text(bounds[p.name]) if p.name in bounds else ""))
        if not more:
            break
    return out


def parameters_text(method: str) -> str:
    """The table `-p help` prints: one line per parameter, then how to set one."""
    params = explorer_parameters(method)
    if not params:
        return f"method {method!r} takes no parameters"
    w_name = max(len(p.name) for p in params)
    w_kind = max(len(p.kind) for p in params)
    w_def = max(len(p.default) for p in params)
    w_range = max(len(p.range) for p in params)
    lines = [f"parameters of {method!r} (set with -p NAME=VALUE; units in brackets; range: the values allowed):"]
    for p in params:
        shown = f"range {p.range:{w_range}}" if p.range else " " * (w_range + 6) if w_range else ""
        lines.append(f"  {p.name:{w_name}}  {p.kind:{w_kind}}  default {p.default:{w_def}}  {shown}  {p.doc}".rstrip())
    return "\n".join(lines)
