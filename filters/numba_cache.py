"""Where numba caches the package's compiled kernels when none of its own places can be written.

The kernels are compiled with ``cache=True``. numba looks for a cache folder at each kernel's
definition: ``$NUMBA_CACHE_DIR``, else the ``__pycache__`` beside the source, else the user's cache
folder (``~/.cache/numba``); with none writable (a read-only install and a read-only or missing home,
as on clusters and in containers) the *import* fails ("no locator available"). `ensure_cache_dir`,
run when the packages are imported, then points numba at a folder in the temp dir instead. It changes
nothing where numba would find a folder itself. Compiling the kernels takes a few seconds once per cache
folder; set ``NUMBA_CACHE_DIR`` to share one between machines or users.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def writable(folder: Path) -> bool:
    """Whether a file can be made in ``folder`` (made if missing), as numba checks its cache folders."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def fallback_dir() -> Path:
    """The cache folder used when numba has none: per user, in the temp dir, private to the user.

    numba's cache files are pickles, loaded as code: a folder in a shared temp dir that another user made
    (or a symlink there) would let them run code in this process. The folder is made with mode 0700 and
    used only if it is a real folder owned by this user and closed to others; otherwise a fresh private
    folder (`tempfile.mkdtemp`) serves this process alone."""
    import stat

    uid = os.getuid() if hasattr(os, "getuid") else None
    folder = Path(tempfile.gettempdir()) / f"semreloc-numba-cache-{uid if uid is not None else 'user'}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(folder)
        if stat.S_ISDIR(st.st_mode) and (uid is None or st.st_uid == uid):
            if st.st_mode & 0o077:  # the user's own folder, opened by a umask or by hand: close it again
                os.chmod(folder, 0o700)
            return folder
    except OSError:
        pass
    fresh = Path(tempfile.mkdtemp(prefix="semreloc-numba-cache-"))
    import atexit
    import shutil
    import warnings

    atexit.register(shutil.rmtree, fresh, ignore_errors=True)
    warnings.warn(
        f"{folder} is not a private folder of this user: numba's kernels are compiled into {fresh} for this "
        "process alone; set NUMBA_CACHE_DIR to a folder of yours to keep them",
        UserWarning,
        stacklevel=2,
    )
    return fresh


def choose_cache_dir(
    in_tree: Path, user_wide: str, configured: str, can_write: Callable[[Path], bool] = writable
) -> Path | None:
    """The folder to give numba, or None to leave its choice: ``configured`` (``NUMBA_CACHE_DIR``) set, the
    ``in_tree`` ``__pycache__`` writable, or an absolute, writable ``user_wide`` folder (a relative one, from a
    missing home, would be made in the working directory) leave it alone."""
    if configured:
        return None
    if can_write(in_tree):
        return None
    if os.path.isabs(user_wide) and can_write(Path(user_wide)):
        return None
    return fallback_dir()


def ensure_cache_dir() -> None:
    """Point numba at `fallback_dir` if it would find no writable cache folder for this package's kernels."""
    import numba
    from numba.misc.appdirs import AppDirs

    chosen = choose_cache_dir(
        Path(__file__).resolve().parent / "__pycache__",
        AppDirs(appname="numba", appauthor=False).user_cache_dir,
        numba.config.CACHE_DIR,
    )
    if chosen is not None:
        # the variable too: numba.config.reload_config(), run when any NUMBA_* variable changes, re-reads it
        os.environ["NUMBA_CACHE_DIR"] = numba.config.CACHE_DIR = str(chosen)
