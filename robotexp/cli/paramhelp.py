"""`robotexp explore -m METHOD -p help` and `--coordinator NAME --coordinator-param help`: an explorer's or
a coordinator's parameters with their types, defaults and units, read from the plugin's signature, its
declared ranges (`parameter_bounds`) and the "Args:" section of its class docstring (units in brackets)."""

from __future__ import annotations

import inspect
import re
import sys
import textwrap
from dataclasses import dataclass

__all__ = ["Parameter", "explorer_parameters", "coordinator_parameters", "parameters_text"]


@dataclass(frozen=True)
class Parameter:
    """One keyword parameter of a plugin."""

    name: str
    kind: str           # its annotation as written ("float", "int | None", ...)
    default: str        # repr of the default, or "required"
    doc: str            # its line of the docstring's Args (the unit first, in brackets), or ""
    range: str = ""     # its declared range ("1..100000", ">= 0"; `Explorer.parameter_bounds`), or ""


WIDTH = 120        # the help text's width: longer descriptions go on indented lines


def _arg_docs(doc: str, refs: dict[str, str] | None = None) -> dict[str, str]:
    """name -> description of the "Args:" section of a Google-style docstring (continuation lines joined).

    A line naming several parameters that another class describes ("a, b: see `Other`") gives no
    description; its names go to `refs` (name -> "Other")."""
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
        ref = re.match(r"\s*([A-Za-z_][A-Za-z0-9_, ]*):\s*see `?([A-Za-z_][A-Za-z0-9_.]*)`?", line)
        if width == indent and ref and not m:
            current = None          # its continuation lines qualify the other class's words: left out
            for name in ref.group(1).split(","):
                if refs is not None and name.strip():
                    refs[name.strip()] = ref.group(2)
        elif width == indent and m:
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
    from robotexp.registry import EXPLORERS, load

    return _parameters(load(EXPLORERS, method, Explorer))


def coordinator_parameters(name: str) -> list[Parameter]:
    """The keyword parameters of coordinator plugin `name`.

    Raises:
        PluginError: unknown coordinator.
    """
    from robotexp.coordinator import Coordinator
    from robotexp.registry import COORDINATORS, load

    return _parameters(load(COORDINATORS, name, Coordinator))


def _parameters(cls: type) -> list[Parameter]:
    """The keyword parameters of plugin class `cls`."""
    from robotexp.registry import bounds_text, parameter_bounds

    bounds = parameter_bounds(cls)
    docs: dict[str, str] = {}
    refs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):          # a subclass's words win
        docs.update(_arg_docs(inspect.getdoc(klass) or "", refs))
    for name, other in refs.items():             # "see `Other`": the words of that class of the plugin
        if not docs.get(name):
            docs[name] = _referred(cls, other).get(name, "")
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
            default = "required" if p.default is inspect.Parameter.empty else _default(p.default)
            out.append(Parameter(p.name, kind, default, _clean(docs.get(p.name, "").split(" **kwargs")[0]),
                                 bounds_text(bounds[p.name]) if p.name in bounds else ""))
        if not more:
            break
    return out


def _referred(cls: type, name: str) -> dict[str, str]:
    """The Args of class `name` (a docstring's "see `name`") as the modules of `cls` and its bases know it."""
    for klass in cls.__mro__:
        other = getattr(sys.modules.get(klass.__module__), name.rsplit(".", 1)[-1], None)
        if isinstance(other, type):
            docs: dict[str, str] = {}
            for base in reversed(other.__mro__):
                docs.update(_arg_docs(inspect.getdoc(base) or ""))
            return docs
    return {}


def _clean(text: str) -> str:
    """A description for the help table: no code quotes, no pointers to other parts of a docstring."""
    text = re.sub(r"[:;,]?\s*\(?see (above|below|`[^`]*`)\)?", "", text)
    return re.sub(r"\s+", " ", text.replace("`", "")).strip()


def _default(value: object) -> str:
    """A default as the help shows it: a float to 6 significant digits (0.261799, not 0.2617993877991494)."""
    text = repr(value)
    return f"{value:.6g}" if isinstance(value, float) and len(text) > 10 else text


def parameters_text(method: str, coordinator: bool = False) -> str:
    """The table `-p help` prints for explorer `method` (`--coordinator-param help` for coordinator `method`,
    with `coordinator`): one line per parameter, then how to set one."""
    params = coordinator_parameters(method) if coordinator else explorer_parameters(method)
    what, option = ("coordinator", "--coordinator-param") if coordinator else ("method", "-p")
    if not params:
        return f"{what} {method!r} takes no parameters"
    w_name = max(len(p.name) for p in params)
    w_kind = max(len(p.kind) for p in params)
    w_def = max(len(p.default) for p in params)
    w_range = max(len(p.range) for p in params)
    lines = [f"parameters of {method!r} (set with {option} NAME=VALUE; units in brackets; range: the values allowed):"]
    for p in params:
        shown = f"range {p.range:{w_range}}  " if p.range else " " * (w_range + 8) if w_range else ""
        head = f"  {p.name:{w_name}}  {p.kind:{w_kind}}  default {p.default:{w_def}}  {shown}"
        if len(head) > WIDTH - 40:       # a long type or range: the description on the lines below
            lines.append(head.rstrip())
            lines += ["      " + more for more in textwrap.wrap(p.doc, WIDTH - 6)]
            continue
        wrapped = textwrap.wrap(p.doc, WIDTH - len(head)) or [""]
        lines.append((head + wrapped[0]).rstrip())
        lines += [" " * len(head) + more for more in wrapped[1:]]
    return "\n".join(lines)
