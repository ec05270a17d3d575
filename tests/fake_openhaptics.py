"""A fake of the pyOpenHaptics binding (pyOpenHaptics 1.0.1, OpenHaptics HD 3.x): the names
`devices/openhaptics.py` uses, with the binding's signatures and conventions.

Mirrored from pyOpenHaptics/hd.py, hd_callback.py and hd_device.py of the 1.0.1 wheel:
* `hd.init_device(name="Default Device")` returns the handle; when hdInitDevice fails it returns
  HD_INVALID_HANDLE (0xFFFFFFFF) silently: the binding compares the handle with the error code
  HD_BAD_HANDLE (0x0104), so its DeviceInitException / print / None path never runs;
* after a failed hdInitDevice, `hd.get_vendor()` / `hd.get_model()` (hdGetString with no
  device) raise AttributeError - hdGetString returns NULL and the binding calls `.decode()` on
  None - unless `strings_without_device = "ok"` (then HapticDevice finishes with that id);
* `hd.get_transform()` a column-major 4x4 `(c_double * 4) * 4` (translation in [3][0..2], mm),
  `hd.get_gimbals()` a `c_double * 3` (rad), `hd.get_buttons()` an int,
  `hd.set_force(feedback)` takes 3 floats (N) and returns None, `hd.get_error()` a bool (and
  prints), `hd.get_model()` / `hd.get_vendor()` strs, `hd._get_doublev(code, dtype)` a ctypes
  value; `hd.start_scheduler()`, `hd.stop_scheduler()`, `hd.enable_force()` (prints),
  `hd.close_device(id)` (hdDisableDevice), `hd.begin_frame(id)`, `hd.end_frame(id)`,
  `hd.get_current_device()`; the HD_* constants of hd_define that are used;
* `hd_callback(fn)` wraps `fn()` between begin_frame and end_frame and returns
  HD_CALLBACK_DONE (0) - the scheduler stops calling it - when get_error() is true after the
  frame, else HD_CALLBACK_CONTINUE (1); an exception escaping `fn` ends it as well (ctypes
  prints it and the callback returns 0);
* `HapticDevice(callback, device_name="Default Device", scheduler_type="async")` prints, calls
  init_device, enable_force, start_scheduler, get_error, then schedules the callback;
  `close()` is stop_scheduler then close_device. The real scheduler runs the callback in a
  thread of its own, one frame after another, concurrently with the application.

The scheduler is stepped by the test: `step(n)` runs every scheduled callback n times (a
haptic frame each), or `start_thread()` runs it at about 1 kHz in a thread of its own. The
device behind it (`pose_mm`, `rotation`, `gimbals`, `buttons`) is scriptable, and so is how it
fails: `init_fails` (init_device returns None), `error_frames` (that many next frames end with
an HD error, which ends the callback), `raise_in` (names of `hd` functions that raise),
`garbage` (readings NaN or None). Every force the device received is kept in `forces` as
(fx, fy, fz) in N, device frame; `force` is what it renders now (zero once the scheduler
stops: what the motors do after hdStopScheduler is not documented, so the fake keeps the last
force written, and a test sees what the adapter left).
"""

from __future__ import annotations

import ctypes
import math
import threading
import time
import types

HD_CALLBACK_DONE, HD_CALLBACK_CONTINUE = 0, 1
HD_NOMINAL_MAX_FORCE, HD_NOMINAL_MAX_CONTINUOUS_FORCE = 0x2603, 0x2604
HD_BAD_HANDLE, HD_INVALID_HANDLE = 0x0104, 0xFFFFFFFF
hduMatrix = (ctypes.c_double * 4) * 4
hduVector3Dd = ctypes.c_double * 3


class FakeOpenHaptics:
    """The binding as `devices.openhaptics.load_binding` returns it: `.hd`, `.HapticDevice`,
    `.hd_callback`, over one scriptable device and a stepped scheduler."""

    def __init__(self, model="Touch", peak=3.3, continuous=0.88, give_limits=True):
        self.model = model
        self.limits = {HD_NOMINAL_MAX_FORCE: peak, HD_NOMINAL_MAX_CONTINUOUS_FORCE: continuous}
        self.give_limits = give_limits
        self.pose_mm = [0.0, 0.0, 0.0]
        self.rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]  # rows
        self.gimbals = [0.0, 0.0, 0.0]
        self.buttons = 0
        self.init_fails = False
        self.strings_without_device = "null"  # hdGetString after a failed init: "null" (raises) or "ok"
        self.device_ok = False                # the last init_device succeeded
        self.set_force_hook = None            # called with the force inside set_force, before it lands
        self.error_frames = 0
        self.raise_in: set[str] = set()
        self.garbage = None
        self.forces: list[tuple] = []
        self.force = (0.0, 0.0, 0.0)
        self.scheduled: list = []
        self.running = False
        self.inits = 0
        self.disabled: list = []
        self.printed: list[str] = []
        self._error = False
        self._lock = threading.Lock()  # the fake's own bookkeeping between its thread and the test
        self._thread = None
        self._stop_thread = False
        self.hd = self._module()
        self.HapticDevice = self._device_class()
        self.hd_callback = self._hd_callback

    # -- the hd module ------------------------------------------------------------------------

    def _check(self, name):
        if name in self.raise_in:
            raise OSError(f"{name}: device fault")

    def _value(self, v):
        return {None: v, "nan": math.nan, "none": None}[self.garbage]

    def _module(self):
        fake = self
        hd = types.SimpleNamespace(HD_NOMINAL_MAX_FORCE=HD_NOMINAL_MAX_FORCE,
                                   HD_NOMINAL_MAX_CONTINUOUS_FORCE=HD_NOMINAL_MAX_CONTINUOUS_FORCE,
                                   HD_CALLBACK_DONE=HD_CALLBACK_DONE, HD_CALLBACK_CONTINUE=HD_CALLBACK_CONTINUE)

        def init_device(name: str = "Default Device"):
            fake.inits += 1
            handle = HD_INVALID_HANDLE if fake.init_fails else fake.inits
            fake.device_ok = not fake.init_fails
            if handle == HD_BAD_HANDLE:  # the binding's own test, never true of a handle
                print("Unable to initialize the device. Check the connection!")
                return None
            return handle

        def get_transform():
            fake._check("get_transform")
            m = hduMatrix()
            r = fake.rotation
            for row in range(3):
                for col in range(3):
                    m[col][row] = fake._value(r[row][col]) if fake.garbage != "none" else math.nan
            m[3][0], m[3][1], m[3][2] = (fake._value(v) if fake.garbage != "none" else math.nan
                                         for v in fake.pose_mm)
            m[3][3] = 1.0
            return m

        def get_gimbals():
            fake._check("get_gimbals")
            v = hduVector3Dd()
            for i in range(3):
                v[i] = fake.gimbals[i]
            return v

        def get_buttons() -> int:
            fake._check("get_buttons")
            return None if fake.garbage == "none" else fake.buttons

        def set_force(feedback) -> None:
            fake._check("set_force")
            v = hduVector3Dd(*feedback)  # as _set_doublev: exactly 3 doubles
            f = (v[0], v[1], v[2])
            if fake.set_force_hook is not None:
                fake.set_force_hook(f)
            fake.forces.append(f)
            fake.force = f

        def get_error() -> bool:
            if fake._error:
                fake._error = False
                print("DeviceInitException: Error during the main scheduler.")
                return True
            return False

        def _get_doublev(code: int, dtype):
            if not fake.give_limits or code not in fake.limits:
                return dtype()  # hdGetDoublev leaves an unknown parameter's buffer as it was: 0
            return dtype(fake.limits[code])

        def start_scheduler() -> None:
            fake.running = True

        def stop_scheduler() -> None:
            fake.running = False
            fake.scheduled.clear()

        def enable_force() -> None:
            print("Force feedback enabled!")

        def close_device(id: int):
            fake.disabled.append(id)

        def begin_frame(id: int) -> None:
            pass

        def end_frame(id: int) -> None:
            if fake.error_frames > 0:
                fake.error_frames -= 1
                fake._error = True

        def get_current_device():
            return fake.inits

        def _string(value):
            if not fake.device_ok and fake.strings_without_device == "null":
                return None.decode()  # AttributeError, as hdGetString's NULL in the binding
            return value

        def get_model() -> str:
            return _string(fake.model)

        def get_vendor() -> str:
            return _string("3D Systems")

        for f in (init_device, get_transform, get_gimbals, get_buttons, set_force, get_error, _get_doublev,
                  start_scheduler, stop_scheduler, enable_force, close_device, begin_frame, end_frame,
                  get_current_device, get_model, get_vendor):
            setattr(hd, f.__name__, f)
        return hd

    # -- hd_callback and HapticDevice --------------------------------------------------------

    def _hd_callback(self, input_function):
        hd = self.hd

        def _callback(pUserData=None):
            hd.begin_frame(hd.get_current_device())
            try:
                input_function()
            except Exception as exc:  # ctypes prints it; the C callback returns 0: DONE
                print(f"Exception ignored on calling ctypes callback function: {exc!r}")
                return HD_CALLBACK_DONE
            hd.end_frame(hd.get_current_device())
            if hd.get_error():
                return HD_CALLBACK_DONE
            return HD_CALLBACK_CONTINUE
        _callback.__wrapped__ = input_function
        return _callback

    def _device_class(self):
        fake = self
        hd = self.hd

        class HapticDevice:
            def __init__(self, callback, device_name: str = "Default Device", scheduler_type: str = "async"):
                print("Initializing haptic device with name {}".format(device_name))
                self.id = hd.init_device(device_name)
                print("Intialized device! {}/{}".format(hd.get_vendor(), hd.get_model()))
                hd.enable_force()
                hd.start_scheduler()
                if hd.get_error():
                    SystemError()
                self.scheduler(callback, scheduler_type)

            def close(self):
                hd.stop_scheduler()
                hd.close_device(self.id)

            def scheduler(self, callback, scheduler_type):
                fake.scheduled.append(callback)  # hdScheduleAsynchronous / hdScheduleSynchronous

        return HapticDevice

    # -- the scheduler -----------------------------------------------------------------------

    def step(self, n: int = 1) -> None:
        """n haptic frames: every scheduled callback once per frame; DONE unschedules it."""
        for _ in range(n):
            if not self.running:
                return
            for cb in list(self.scheduled):
                if cb(None) == HD_CALLBACK_DONE and cb in self.scheduled:
                    self.scheduled.remove(cb)

    def start_thread(self) -> None:
        def run():
            next_t = time.perf_counter()
            while not self._stop_thread:
                self.step(1)
                next_t += 0.001
                time.sleep(max(0.0, next_t - time.perf_counter()))
        self._stop_thread = False
        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()

    def stop_thread(self) -> None:
        self._stop_thread = True
        if self._thread is not None:
            self._thread.join(1.0)
