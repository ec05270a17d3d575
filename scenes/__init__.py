"""The scenes shipped with softproxy: MJCF worlds plus a TOML file describing the fingers."""
from pathlib import Path

DIRECTORY = Path(__file__).resolve().parent
