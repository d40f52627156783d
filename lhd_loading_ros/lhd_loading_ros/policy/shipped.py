"""Where the YAML files shipped with the project live: `config/` of the source tree, else the
installed copy in share/lhd_loading_ros/config (colcon)."""
from __future__ import annotations

from pathlib import Path


def shipped_config(relpath: str) -> Path:
    """The shipped file config/<relpath>; FileNotFoundError naming where it was looked for."""
    looked = []
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "config" / relpath
        looked.append(str(cand))
        if cand.is_file():
            return cand
        if (parent / "config" / "lhd_params.yaml").is_file():
            break                      # the source tree's config folder: no need to go higher
    try:  # colcon install: share/lhd_loading_ros/config
        from ament_index_python.packages import get_package_share_directory

        cand = Path(get_package_share_directory("lhd_loading_ros")) / "config" / relpath
        looked.append(str(cand))
        if cand.is_file():
            return cand
    except Exception:  # noqa: BLE001 - ament index absent or package not installed there
        pass
    raise FileNotFoundError(f"config/{relpath} not found (looked in {', '.join(looked)})")
