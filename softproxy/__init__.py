"""softproxy: a haptic rendering engine with 4-DOF soft-finger proxies on a MuJoCo world.

Import what you need from the submodules; the names below are the small public surface.
Nothing here imports GL, HID or the `devices` package.
"""

from softproxy.fingertip import MODELS, FingertipModel, model
from softproxy.torsion import TorsionalFriction

__version__ = "0.1.0"

__all__ = ["MODELS", "FingertipModel", "TorsionalFriction", "model", "__version__"]
