"""softproxy: a haptic rendering engine with 4-DOF soft-finger proxies on a MuJoCo world.

The public surface: build a `World` from a MuJoCo model, give it `SoftFingerProxy` fingers,
and drive them through a `ServoLoop` from any object that speaks the `Device` protocol —
or load a shipped scene with `load_scene` and `build`. Nothing here imports GL, HID or
the `devices` package.
"""

from softproxy import working_folder  # noqa: F401  (first: nothing from the working folder runs)
from softproxy.device import Device, DeviceError, DeviceSample
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import MODELS, FingertipModel, model
from softproxy.schema import Material
from softproxy.run import build, open_device, run_scene
from softproxy.scene import Scene, SceneError, load_scene
from softproxy.servo import ServoLoop
from softproxy.torsion import TorsionalFriction
from softproxy.world import World

__version__ = "0.1.0"

__all__ = [
    "Device", "DeviceError", "DeviceSample", "FingerParams", "FingertipModel", "MODELS", "Material", "Scene",
    "SceneError", "ServoLoop", "SoftFingerProxy", "TorsionalFriction", "World", "build", "load_scene",
    "model", "open_device", "run_scene", "__version__",
]
