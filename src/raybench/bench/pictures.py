"""A record's picture: what a point of the scenes suite traced, small enough to ride in its
record (a JPEG of at most WIDTH pixels across, as a data: URI), so that the report can show
each real scene beside its times wherever the results file goes."""

from __future__ import annotations

import base64
import io
import re

import numpy as np

WIDTH = 320
QUALITY = 85
PREFIX = "data:image/jpeg;base64,"
MAX_CHARS = 200_000  # far above any 320-pixel JPEG at QUALITY: a longer one was not made here
PATTERN = re.compile(re.escape(PREFIX) + r"[A-Za-z0-9+/]+={0,2}")


def thumbnail(image: np.ndarray) -> str:
    """An (H, W, 3) uint8 RGB frame, scaled to WIDTH pixels across (never up), as a data: URI."""
    from PIL import Image

    picture = Image.fromarray(image, "RGB")
    if picture.width > WIDTH:
        picture = picture.resize((WIDTH, max(1, round(picture.height * WIDTH / picture.width))), Image.LANCZOS)
    buffer = io.BytesIO()
    picture.save(buffer, format="JPEG", quality=QUALITY, subsampling=0)  # 4:4:4: a small frame keeps its colours
    return uri(buffer.getvalue())


def uri(jpeg_file: bytes) -> str:
    """A JPEG file as a data: URI, as a record and report.html hold it."""
    return PREFIX + base64.b64encode(jpeg_file).decode("ascii")


def jpeg(uri: str) -> bytes:
    """The JPEG file a record's picture holds."""
    return base64.b64decode(uri[len(PREFIX) :], validate=True)
