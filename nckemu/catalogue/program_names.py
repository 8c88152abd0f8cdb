"""NC file names as the control writes them (``/_N_MPF_DIR/_N_TEST_MPF``) and as users do
(``TEST.MPF``, ``WARMUP_CYCLE.SPF``): shared by the emulator's program store and the clients that send
programs to a real control.

Sources: ../shared/reference/programs.md §7 (internal names ``_N_<NAME>_MPF``/``_SPF``/``_WPD``,
directories ``_N_<X>_DIR``; names of letters, digits and underscores, at most 24 characters,
case-insensitive).
"""

from __future__ import annotations

import re

from nckemu.errors import NckPiBadArguments

# File types and the directory a bare name of that type lives in.
# GUD and R values files (NAME.GUD, NAME.RPA) go beside the definitions (our choice: a control keeps them
# in a workpiece's directory or a data backup).
TYPE_DIRECTORIES = {"MPF": "_N_MPF_DIR", "SPF": "_N_SPF_DIR", "DEF": "_N_DEF_DIR", "GUD": "_N_DEF_DIR",
                    "RPA": "_N_DEF_DIR"}
# Directories every NCK has (part programs, subprograms, workpieces), even when empty.
DIRECTORIES = ("/_N_MPF_DIR", "/_N_SPF_DIR", "/_N_WKS_DIR")
_CONTROL_NAME = re.compile(r"_N_([A-Z0-9_]+)_(MPF|SPF|DEF|GUD|RPA|INI|WPD)")
_USER_NAME = re.compile(r"([A-Z0-9_]+)\.(MPF|SPF|DEF|GUD|RPA|INI)")
_DIRECTORY = re.compile(r"_N_[A-Z0-9_]+_(DIR|WPD)")
MAX_NAME_CHARS = 24


def program_path(name: str, *, default_type: str = "MPF") -> str:
    """The control's path of a program named as a user or the control writes it.

    ``TEST.MPF`` and ``_N_TEST_MPF`` give ``/_N_MPF_DIR/_N_TEST_MPF``; ``/_N_SPF_DIR/_N_X_SPF`` stays
    as it is; a bare ``TEST`` is of ``default_type``. Names are case-insensitive (kept in upper case).
    Raises NckPiBadArguments for anything that is not an NC file name (``..``, empty parts, spaces).
    """
    text = name.strip().upper()
    parts = [part for part in text.split("/") if part]
    if not parts or any(part in (".", "..") for part in parts) or "\\" in text:
        raise NckPiBadArguments(f"{name!r} is not an NC file name")
    *directories, leaf = parts
    control = _CONTROL_NAME.fullmatch(leaf)
    user = _USER_NAME.fullmatch(leaf)
    if control:
        stem, kind = control.group(1), control.group(2)
    elif user:
        stem, kind = user.group(1), user.group(2)
    elif re.fullmatch(r"[A-Z_][A-Z0-9_]*", leaf):
        stem, kind = leaf, default_type
    else:
        raise NckPiBadArguments(f"{name!r} is not an NC file name (letters, digits and _ only)")
    if len(stem) > MAX_NAME_CHARS:
        raise NckPiBadArguments(f"{name!r}: a program name has at most {MAX_NAME_CHARS} characters")
    control_dirs = []
    for directory in directories:
        if not directory.startswith("_N_"):
            directory = "_N_" + directory.replace(".", "_")
        if not _DIRECTORY.fullmatch(directory):
            raise NckPiBadArguments(f"{name!r}: {directory} is not an NC directory")
        control_dirs.append(directory)
    if not control_dirs:
        control_dirs = [TYPE_DIRECTORIES.get(kind, "_N_MPF_DIR")]
    return "/" + "/".join([*control_dirs, f"_N_{stem}_{kind}"])


def directory_path(name: str) -> str | None:
    """``_N_MPF_DIR`` -> ``/_N_MPF_DIR``, ``_N_PART_WPD`` -> ``/_N_WKS_DIR/_N_PART_WPD``, a full path of
    directories as it is (upper case); None when ``name`` does not end in a directory."""
    text = name.strip().upper()
    parts = [part for part in text.split("/") if part]
    if not parts or not all(_DIRECTORY.fullmatch(part) for part in parts):
        return None
    if len(parts) == 1 and parts[0].endswith("_WPD"):
        parts = ["_N_WKS_DIR", *parts]
    return "/" + "/".join(parts)


def user_name(path: str) -> str:
    """``/_N_MPF_DIR/_N_TEST_MPF`` -> ``TEST.MPF`` (the name an HMI shows)."""
    leaf = path.rsplit("/", 1)[-1]
    match = _CONTROL_NAME.fullmatch(leaf)
    return f"{match.group(1)}.{match.group(2)}" if match else leaf
