"""A backend of one's own for the registration tests: the numpy reference under another name."""

from cansim.backends.numpy_backend import NumpyBackend


class MineBackend(NumpyBackend):
    """The numpy reference named ``"mine"``."""

    name = "mine"
