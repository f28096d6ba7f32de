"""raybench.gif: a sequence's PNGs as one animated GIF."""

import numpy as np
import pytest
from PIL import Image

from raybench import RaybenchError
from raybench.gif import FPS, write_gif
from raybench.render import png_bytes

COLOURS = [(255, 0, 0), (0, 160, 255), (20, 200, 40)]


def frames(tmp_path, colours=COLOURS, size=(24, 16)):
    paths = []
    for n, colour in enumerate(colours):
        image = np.zeros((size[1], size[0], 3), np.uint8)
        image[:, : size[0] // 2] = colour  # half the frame its colour, half black
        path = tmp_path / f"frame_{n:05d}.png"
        path.write_bytes(png_bytes(image))
        paths.append(path)
    return paths


def test_the_frames_in_order_looping_at_fps(tmp_path):
    out = tmp_path / "orbit.gif"
    write_gif(frames(tmp_path), out)
    with Image.open(out) as gif:
        assert gif.format == "GIF" and gif.size == (24, 16) and gif.n_frames == len(COLOURS)
        assert gif.info["loop"] == 0
        for n, colour in enumerate(COLOURS):
            gif.seek(n)
            assert gif.info["duration"] == 1000 / FPS
            pixels = np.asarray(gif.convert("RGB"))
            assert tuple(pixels[0, 0]) == colour and tuple(pixels[0, -1]) == (0, 0, 0)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # written atomically, no leftovers


@pytest.mark.parametrize(
    "name, frame_count, message",
    [
        ("orbit.png", 3, "must be a .gif file"),
        ("missing/orbit.gif", 3, "does not exist"),
        ("orbit.gif", 0, "no frames"),
    ],
)
def test_refused_in_one_line(tmp_path, name, frame_count, message):
    with pytest.raises(RaybenchError, match=message):
        write_gif(frames(tmp_path, COLOURS[:frame_count]), tmp_path / name)
    assert not (tmp_path / name).exists()
