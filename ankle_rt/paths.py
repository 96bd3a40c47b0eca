"""Where the shipped configuration files are: the repository's ``config/`` directory beside the
package. ankle-rt is installed from a checkout (``pip install -e .``), so the files users edit and
the defaults the commands load are the same files; there is no second copy as package data."""

from __future__ import annotations

from pathlib import Path

from ankle_rt.config import ConfigError

CONFIG_DIR = Path(__file__).resolve().parent.parent / "config"


def default_config_path(name: str = "sim.yaml") -> Path:
    """The shipped config ``name``; a ConfigError says what to do when the checkout is not there."""
    path = CONFIG_DIR / name
    if not path.is_file():
        raise ConfigError("the default config is not there (ankle-rt expects to run from a checkout, "
                          "installed with pip install -e .); pass --config FILE", str(path))
    return path
