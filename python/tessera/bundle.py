"""What a submission is made of, read on the client's side: the scene bundle (the scene
file and every file it references, each with its SHA-256), the frames to render and the
job's default name.

These mirror the C++ CLI (common/bundle.cpp, cli/frame_list.cpp, cli/job_options.cpp) so
that `tessera submit` and `Client.submit` send the same job for the same scene. The CLI
asks the engine's scene parser which files a scene references; here the scene's JSON is
read directly and every string value of a "file" key is taken as a reference. That is
exact: the scene format (docs/scene-format.md) names files only under "file" (image
textures, measured materials, meshes, mesh deformation keys, environment lights), and
the coordinator refuses any key the format does not know. The coordinator also loads the
scene before it accepts the job, so a reference missing from the bundle is reported
(INVALID_ARGUMENT, naming the file) rather than rendered wrong.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, Iterable, List, Optional, Union

# The coordinator's bound on frame numbers, and the most frames one list may hold
# (cli/frame_list.h).
MAX_FRAME = 10_000_000
MAX_FRAMES = 100_000

FRAME_LIST_SYNTAX = "expected A, A-B, A-B:step or a comma list of them"

# ValidateBundlePath's bound (common/bundle.h).
_MAX_BUNDLE_PATH_BYTES = 1024
_HASH_BLOCK = 1 << 20


@dataclass(frozen=True)
class BundleFile:
    """One file of a scene bundle."""

    path: str  # in the bundle: relative to the scene's folder, "/"-separated
    local_path: Path  # where it is on this machine
    sha256: str  # lowercase hex
    size: int  # bytes


def strip_json_comments(text: str) -> str:
    """The text without `// line` and `/* block */` comments outside strings, which the
    engine's JSON reader accepts (nlohmann-json's ignore_comments) and Python's does not.
    A comment becomes a space (or its newlines), so that error positions stay right."""
    out: List[str] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append(text[i : j + 1])
            i = j + 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
            out.append(" ")
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            if j < 0:
                raise ValueError("unterminated /* comment")
            out.append(" " + "\n" * text.count("\n", i, j))
            i = j + 2
        else:
            out.append(c)
            i += 1
    return "".join(out)


def read_scene(scene_path: Union[str, os.PathLike]) -> dict:
    """The scene file's JSON as a dict. Raises OSError if it cannot be read and
    ValueError (naming the file, line and column) if it is not a JSON object."""
    path = Path(scene_path)
    text = path.read_text(encoding="utf-8")
    try:
        scene = json.loads(strip_json_comments(text))
    except ValueError as e:
        raise ValueError(f"{path}: not a scene file: {e}") from None
    if not isinstance(scene, dict):
        raise ValueError(f"{path}: not a scene file: the top level is not a JSON object")
    return scene


def referenced_files(scene: Any) -> List[str]:
    """The files a parsed scene references, as written, each once, in document order."""
    found: List[str] = []

    def walk(value: Any) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                if key == "file" and isinstance(item, str):
                    if item not in found:
                        found.append(item)
                else:
                    walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)

    walk(scene)
    return found


def validate_bundle_path(path: str) -> Optional[str]:
    """None if `path` is a safe bundle path (relative, "/"-separated, no empty, "." or
    ".." components, no backslashes or control characters, at most 1024 bytes); else
    what is wrong with it."""
    if not path:
        return "path is empty"
    if len(path.encode("utf-8")) > _MAX_BUNDLE_PATH_BYTES:
        return "path is longer than 1024 bytes"
    if path.startswith("/"):
        return f"path '{path}' is absolute"
    if "\\" in path:
        return f"path '{path}' contains a backslash"
    if any(ord(c) < 0x20 for c in path):
        return "path contains a control character"
    for part in path.split("/"):
        if part in ("", "."):
            return f"path '{path}' has an empty or '.' component"
        if part == "..":
            return f"path '{path}' escapes the scene's folder"
    return None


def file_sha256(path: Union[str, os.PathLike]) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(_HASH_BLOCK), b""):
            digest.update(block)
    return digest.hexdigest()


def collect_bundle(scene_path: Union[str, os.PathLike]) -> List[BundleFile]:
    """The scene file (first) and every file it references. Raises ValueError if the
    scene does not parse or a reference leaves the scene's folder or uses "..", and
    OSError if a file cannot be read."""
    scene_file = Path(os.path.abspath(scene_path))
    root = scene_file.parent
    written = [scene_file.name] + referenced_files(read_scene(scene_file))
    entries: List[BundleFile] = []
    for rel in written:
        pure = PurePosixPath(rel)
        if pure.is_absolute() or os.path.isabs(rel):
            raise ValueError(
                f"'{rel}' is outside the scene's folder {root}: a bundle holds only files "
                "beside or below the scene"
            )
        # The farm loads the scene sandboxed, which refuses any "..".
        if ".." in pure.parts:
            raise ValueError(
                f"'{rel}' contains '..': a scene sent to the farm may refer to its files "
                "only by paths without '..'"
            )
        bundle_path = str(pure)  # drops "./" and repeated slashes, as lexically_normal
        why = validate_bundle_path(bundle_path)
        if why is not None:
            raise ValueError(f"{scene_file}: {why}")
        if any(e.path == bundle_path for e in entries):
            continue
        local = root / bundle_path
        if not local.is_file():
            raise FileNotFoundError(f"{scene_file} refers to '{rel}': {local} is not a file")
        entries.append(BundleFile(bundle_path, local, file_sha256(local), local.stat().st_size))
    return entries


_DIGITS = re.compile(r"[0-9]+")


def _bad(item: str, why: str) -> ValueError:
    return ValueError(f"{FRAME_LIST_SYNTAX}: '{item}' {why}")


def _frame_number(digits: str, item: str) -> int:
    if not digits:
        raise _bad(item, "lacks a number")
    if not _DIGITS.fullmatch(digits):
        raise _bad(item, "is not made of numbers")
    if len(digits) > 9 or int(digits) > MAX_FRAME:
        raise _bad(item, f"names a frame above {MAX_FRAME}")
    return int(digits)


def _frame_item(item: str) -> range:
    if not item:
        raise _bad(item, "is empty")
    dash = item.find("-")
    if dash < 0:
        if ":" in item:
            raise _bad(item, "has a step but no range")
        first = _frame_number(item, item)
        return range(first, first + 1)
    colon = item.find(":", dash)
    first = _frame_number(item[:dash], item)
    last = _frame_number(item[dash + 1 : colon if colon >= 0 else len(item)], item)
    step = 1
    if colon >= 0:
        text = item[colon + 1 :]
        if not text:
            raise _bad(item, "lacks a step after ':'")
        if not _DIGITS.fullmatch(text):
            raise _bad(item, "has a step that is not a number")
        if len(text) > 9 or int(text) < 1:
            raise _bad(item, "has a step below 1 or too large")
        step = int(text)
    if last < first:
        raise _bad(item, "ends before it starts")
    count = (last - first) // step + 1
    if count > MAX_FRAMES:
        raise _bad(item, f"holds {count} frames; at most {MAX_FRAMES} are allowed")
    return range(first, last + 1, step)


def parse_frame_list(text: str) -> List[int]:
    """`--frames` syntax: "A", "A-B" (inclusive), "A-B:step" or a comma list of them, e.g.
    "1-9:2,20,30-32". Sorted, without duplicates; ValueError for anything else."""
    if not text:
        raise ValueError(f"{FRAME_LIST_SYNTAX}: empty")
    frames: set = set()
    for item in text.split(","):
        frames.update(_frame_item(item))
        if len(frames) > MAX_FRAMES:
            raise ValueError(f"'{text}' holds more than {MAX_FRAMES} frames")
    return sorted(frames)


def frames_of(frames: Union[int, str, Iterable[int]]) -> List[int]:
    """A job's frames from what a caller gives: one frame number, a frame-list string or
    numbers (a range, a list). Sorted, without duplicates; ValueError if empty or out of
    [0, MAX_FRAME]."""
    if isinstance(frames, str):
        return parse_frame_list(frames)
    if isinstance(frames, bool):
        raise TypeError("frames must be a frame number, a frame list or numbers, not a bool")
    numbers = [frames] if isinstance(frames, int) else list(frames)
    for f in numbers:
        if isinstance(f, bool) or not isinstance(f, int):
            raise TypeError(f"frame {f!r} is not an int")
        if not 0 <= f <= MAX_FRAME:
            raise ValueError(f"frame {f} is outside [0, {MAX_FRAME}]")
    result = sorted(set(numbers))
    if not result:
        raise ValueError("no frames given")
    if len(result) > MAX_FRAMES:
        raise ValueError(f"{len(result)} frames; at most {MAX_FRAMES} are allowed")
    return result


def scene_frames(scene: dict) -> List[int]:
    """The frames the scene's "animation" section names (its "frames": "A-B", "A" or
    [A, B]); frame 0 without one."""
    animation = scene.get("animation")
    spec = animation.get("frames") if isinstance(animation, dict) else None
    if spec is None:
        return [0]
    if isinstance(spec, str):
        m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", spec)
        if not m:
            raise ValueError(f'animation frames: expected "A-B" or [A, B], got "{spec}"')
        first = int(m.group(1))
        last = int(m.group(2)) if m.group(2) is not None else first
    elif isinstance(spec, list) and len(spec) == 2 and all(isinstance(v, int) for v in spec):
        first, last = spec
    else:
        raise ValueError(f"animation frames: expected [first, last] or \"A-B\", got {spec!r}")
    if first < 0 or last < first:
        raise ValueError("animation frames must run from a first frame >= 0 to a last >= it")
    return list(range(first, last + 1))


def default_job_name(scene_path: Union[str, os.PathLike]) -> str:
    """The scene file's stem, or its folder's name for the common "scene.json", with
    characters outside [A-Za-z0-9._-] replaced by "_"."""
    path = Path(os.path.abspath(scene_path))
    name = path.stem
    if name == "scene" and path.parent.name:
        name = path.parent.name
    name = re.sub(r"[^A-Za-z0-9._-]", "_", name)
    return name or "job"


def is_frame_range(frames: List[int]) -> bool:
    """Whether sorted, distinct `frames` are consecutive (what frame_start..frame_end
    alone can say)."""
    return not frames or frames[-1] - frames[0] + 1 == len(frames)
