"""Which motion format a file is, from its extension and its first bytes, before it is read: a
format hlik does not read is named as such (a CMU ``.amc`` is not "malformed XML"), and the check
loads nothing heavy (the CLI runs it before NumPy)."""

from __future__ import annotations

from pathlib import Path

from hlik.util.errors import MotionFormatError
from hlik.util.files import check_readable

# What :func:`hlik.human.load.load_motion` reads, for the messages.
READS = "MMM .xml, .bvh, or a keypoint .toml (joint positions in .csv/.txt/.npy/.npz, or a BVH)"
_READERS = {".xml": "mmm", ".bvh": "bvh", ".toml": "keypoints"}
_SNIFF = 512  # bytes read to recognise a format


def motion_format(path: str | Path) -> str:
    """``mmm``, ``bvh`` or ``keypoints``: how :func:`~hlik.human.load.load_motion` reads ``path``.

    The extension decides where it names a format hlik reads; otherwise the first bytes do (an
    MMM file saved without ``.xml``, a BVH without ``.bvh``).

    Raises:
        hlik.util.errors.MotionFormatError: no such file, a folder, unreadable, or a format hlik
            does not read (named where recognised: C3D, ASF/AMC, FBX, SMPL ``.npz``), with the
            formats it does read.
    """
    path = Path(path)
    head = check_readable(path, lambda problem: MotionFormatError(path, problem), "a motion file", _SNIFF)
    known = _READERS.get(path.suffix.lower())
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if known == "mmm" and text and not text.startswith(b"<"):
        raise MotionFormatError(path, f"not XML (an MMM file begins with '<'); hlik reads {READS}")
    if known == "bvh" and text and not text.upper().startswith(b"HIERARCHY"):
        what = _unsupported("", head)  # what it is instead, where the first bytes tell
        why = f": {what}" if what != UNKNOWN else " (a BVH begins with HIERARCHY)"
        raise MotionFormatError(path, f"not a BVH file{why}; hlik reads {READS}")
    if known is not None:
        return known
    if text.startswith(b"<"):
        return "mmm"
    if text.upper().startswith(b"HIERARCHY"):
        return "bvh"
    raise MotionFormatError(path, f"{_unsupported(path.suffix.lower(), head)}; hlik reads {READS}")


UNKNOWN = "not a motion format hlik recognises"


def _unsupported(suffix: str, head: bytes) -> str:
    """What the file is, where recognised, and that hlik does not read it."""
    if suffix == ".c3d" or (len(head) > 1 and head[1:2] == b"\x50" and suffix in ("", ".c3d")):
        return "a C3D marker file, which hlik does not read (export joint positions as a keypoint take)"
    if suffix in (".amc", ".asf") or head.startswith((b"#!OML:ASF", b":FULLY-SPECIFIED", b"# AST/ASF")):
        return "an ASF/AMC (Acclaim) file, which hlik does not read (convert the take to BVH)"
    if suffix == ".fbx" or head.startswith(b"Kaydara FBX Binary"):
        return "an FBX file, which hlik does not read (export the take as BVH)"
    if suffix in (".npz", ".npy", ".csv", ".txt"):
        return f"a {suffix} array is read through a keypoint .toml that says what its columns are"
    return UNKNOWN
