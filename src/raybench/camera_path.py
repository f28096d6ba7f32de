"""Camera paths: the cameras of a frame sequence, an orbit or keyframes.

An orbit circles the camera's position about its look_at, around its up
axis, in equal steps, frame 0 the camera itself. A keyframes file moves the
camera through its keyframes at an even pace, position, look_at, up and
fov_deg each interpolated linearly, the first frame on the first keyframe
and the last on the last:

    {"format": "raybench-path", "version": 1,
     "keyframes": [{"position": [0, 0, 0], "look_at": [0, 0, 1]}, {"position": [0, 2, -1], "fov_deg": 40}]}

A keyframe's missing keys are the default Camera's.
"""

from __future__ import annotations

import math

import numpy as np

from .camera import Camera
from .errors import RaybenchError, shown
from .files import read_json

FORMAT = "raybench-path"
VERSION = 1
_KEYS = {"position", "look_at", "up", "fov_deg"}
# Frames of one sequence at most: a frame number has five digits.
MAX_FRAMES = 99_999


def check_frames(frames) -> int:
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or not 1 <= frames <= MAX_FRAMES:
        raise RaybenchError(f"frames: must be a whole number from 1 to {MAX_FRAMES}, got {shown(frames)}")
    return int(frames)


def orbit(camera: Camera, frames: int) -> list[Camera]:
    """frames cameras on the circle of camera.position about camera.look_at,
    around camera.up, a full turn in equal steps; frame 0 is camera."""
    frames = check_frames(frames)
    centre = np.array(camera.look_at)
    arm = np.array(camera.position) - centre
    axis = np.array(camera.up) / np.linalg.norm(camera.up)
    out = []
    for i in range(frames):
        angle = 2.0 * math.pi * i / frames
        c, s = math.cos(angle), math.sin(angle)
        # Rodrigues' rotation of the arm about the axis
        turned = arm * c + np.cross(axis, arm) * s + axis * np.dot(axis, arm) * (1.0 - c)
        out.append(Camera(tuple(centre + turned), camera.look_at, camera.up, camera.fov_deg))
    return out


def keyframes(doc, frames: int, where: str = "path") -> list[Camera]:
    """The cameras of a keyframes document (a parsed raybench-path file)."""
    frames = check_frames(frames)
    if not isinstance(doc, dict):
        raise RaybenchError(f'{where}: must be a JSON object with "format": "{FORMAT}"')
    if doc.get("format") != FORMAT:
        raise RaybenchError(f'{where}: format: must be "{FORMAT}", got {shown(doc.get("format"))}')
    if doc.get("version") != VERSION or isinstance(doc.get("version"), bool):
        raise RaybenchError(f"{where}: version: this raybench reads version {VERSION}, got {shown(doc.get('version'))}")
    unknown = sorted(set(doc) - {"format", "version", "keyframes"})
    if unknown:
        raise RaybenchError(f"{where}: {unknown[0]}: unknown key; allowed: format, version, keyframes")
    keys = doc.get("keyframes")
    if not isinstance(keys, list) or not keys:
        raise RaybenchError(f"{where}: keyframes: must be a list of one or more camera objects")
    cameras = []
    for k, key in enumerate(keys):
        at = f"{where}: keyframes[{k}]"
        if not isinstance(key, dict):
            raise RaybenchError(f"{at}: must be an object with position, look_at, up, fov_deg")
        unknown = sorted(set(key) - _KEYS)
        if unknown:
            raise RaybenchError(f"{at}.{unknown[0]}: unknown key; allowed: {', '.join(sorted(_KEYS))}")
        try:
            cameras.append(Camera(**key))
        except RaybenchError as exc:
            raise RaybenchError(f"{at}: {exc}") from None
    out = []
    for i in range(frames):
        s = 0.0 if frames == 1 else i * (len(cameras) - 1) / (frames - 1)
        k = min(int(s), len(cameras) - 2) if len(cameras) > 1 else 0
        a, b = cameras[k], cameras[min(k + 1, len(cameras) - 1)]
        f = s - k

        def mix(p, q, f=f):
            return tuple((1.0 - f) * np.array(p, dtype=np.float64) + f * np.array(q, dtype=np.float64))

        try:
            out.append(Camera(mix(a.position, b.position), mix(a.look_at, b.look_at), mix(a.up, b.up),
                              (1.0 - f) * a.fov_deg + f * b.fov_deg))  # fmt: skip
        except RaybenchError as exc:
            raise RaybenchError(f"{where}: frame {i} (between keyframes {k} and {k + 1}): {exc}") from None
    return out


def load(spec: str, frames: int, camera: Camera | None = None) -> list[Camera]:
    """The cameras of --path: "orbit" (about the scene's camera, else
    Camera()'s position and look_at), else a keyframes file's."""
    if spec == "orbit":
        return orbit(camera or Camera(), frames)
    return keyframes(read_json(spec, "camera path file"), frames, where=str(spec))
