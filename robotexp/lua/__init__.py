"""Lua experiment scripts: the IfTEA API (thesis section 4.2.2) on lupa. Imports lupa."""

from robotexp.lua.api import Control, Session, parse_address
from robotexp.lua.runtime import ScriptResult, run_script, substitute_method

__all__ = ["run_script", "ScriptResult", "substitute_method", "Session", "Control", "parse_address"]
