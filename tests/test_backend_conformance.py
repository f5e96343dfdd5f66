"""Every non-reference backend against the numpy reference: cansim's conformance plugin, run here."""

from cansim.testing.conformance import *  # noqa: F401,F403
