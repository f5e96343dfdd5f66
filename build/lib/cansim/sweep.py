"""Deprecated: moved to :mod:`cansim.tools.sweep` (removed in 0.3)."""
from cansim._moved import alias_module

alias_module(__name__)
