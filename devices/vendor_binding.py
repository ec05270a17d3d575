"""A vendor SDK's Python binding, as the SDK adapters (forcedimension, openhaptics) load it: the
one-line error when it is not installed, and the start of the row `softproxy devices` prints
about the backend (binding installed, SDK found)."""

from __future__ import annotations

from softproxy.device import DeviceError


def missing_binding(exc: ModuleNotFoundError, package: str, name: str, install_hint: str) -> DeviceError:
    """The error of a binding import that found no module: the binding (`package`) not installed,
    or a module it needs missing (`exc.name` says which)."""
    if exc.name and exc.name.split(".")[0] == package:
        return DeviceError(f"the {name} binding is not installed: {install_hint}")
    return DeviceError(f"the {name} binding cannot load ({exc}): {install_hint}")


def availability_row(backend: str, binding, load) -> tuple[dict, object]:
    """(row, binding) for `softproxy devices`: `binding`, else `load()`'s; when that fails the row
    says why (binding True when it is installed but its SDK library is not) and binding is None."""
    row = {"backend": backend, "binding": False, "sdk": False, "devices": None, "message": ""}
    if binding is None:
        try:
            binding = load()
        except DeviceError as exc:
            row["binding"] = "not installed" not in str(exc)
            row["message"] = str(exc)
            return row, None
    row["binding"] = row["sdk"] = True
    return row, binding
