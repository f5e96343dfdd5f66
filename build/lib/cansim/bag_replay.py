"""Deprecated: moved to :mod:`cansim.tools.bag_replay` (removed in 0.3)."""
from cansim._moved import alias_module

alias_module(__name__)
