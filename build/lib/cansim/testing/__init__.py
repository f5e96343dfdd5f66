"""Testing helpers that ship with cansim: the backend conformance suite (:mod:`cansim.testing.conformance`,
:mod:`cansim.testing.plugin`) and synthetic worlds for demos and tests (:mod:`cansim.testing.worlds`)."""
