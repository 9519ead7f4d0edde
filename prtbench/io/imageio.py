"""Image input/output: OpenEXR and Radiance HDR in, EXR and PNG out, the display transform.

HDR images are float32 linear RGB arrays of shape (H, W, 3), row 0 at the top. Display images
(DESIGN.md §7) are ``clip(srgb(exposure · hdr), 0, 1)``; metrics are computed on them as float.
All writes are atomic (temporary file, then rename).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from PIL import Image, UnidentifiedImageError

from prtbench.api.cache import atomic_path
from prtbench.api.errors import InvalidInputError

T = TypeVar("T")


@contextlib.contextmanager
def _library_output() -> Iterator[list[str]]:
    """Capture what libraries write to stderr and stdout inside the block.

    OpenEXR's C++ library reports corrupt chunks on file descriptor 2 itself, and its Python
    binding prints a warning through ``sys.stdout`` (then raises a vaguer exception); either
    would break our one-line error. The captured lines (file descriptors 2 and 1 first, then
    Python's streams) are appended to the yielded list when the block ends, so callers fold
    them into their message.
    """
    lines: list[str] = []
    with contextlib.ExitStack() as stack:
        sinks = []
        for fd, stream in ((2, sys.stderr), (1, sys.stdout)):
            try:
                saved = os.dup(fd)
            except OSError:  # no such descriptor (embedded interpreter): nothing to capture
                continue
            if stream is not None:
                stream.flush()
            sink = stack.enter_context(tempfile.TemporaryFile())
            os.dup2(sink.fileno(), fd)
            sinks.append((fd, stream, saved, sink))
        # The binding also prints through Python's own sys.stdout / sys.stderr objects.
        python_out = stack.enter_context(contextlib.redirect_stdout(io.StringIO()))
        python_err = stack.enter_context(contextlib.redirect_stderr(io.StringIO()))
        try:
            yield lines
        finally:
            texts = []
            for fd, stream, saved, sink in sinks:
                if stream is not None:
                    stream.flush()
                os.dup2(saved, fd)
                os.close(saved)
                sink.seek(0)
                texts.append(sink.read().decode("utf-8", "replace"))
            texts += [python_err.getvalue(), python_out.getvalue()]
            lines.extend(line.strip() for text in texts for line in text.splitlines()
                         if line.strip())


def _exr_error(path: Path, exc: BaseException, lines: list[str]) -> InvalidInputError:
    """One-line error for an unreadable EXR: the library's own first line, then the binding's."""
    reason = " ".join(str(exc).split()) or type(exc).__name__
    if lines:
        first = lines[0]
        # The library prefixes its lines with the file name: keep only the reason.
        first = first[len(str(path)) + 1:].strip() if first.startswith(f"{path}:") else first
        reason = f"{first} ({reason})"
    return InvalidInputError(f"cannot read EXR '{path}': {reason}")


def _openexr_call(path: Path, read: Callable[[Any], T]) -> T:
    """``read(OpenEXR)`` with the library's console output captured, failures as one line.

    Both readers below go through here so that whatever OpenEXR prints (on the C++ side or
    through the binding) ends up in the :class:`InvalidInputError`, never on the console.
    """
    import OpenEXR

    with _library_output() as lines:
        try:
            value = read(OpenEXR)
        except Exception as exc:  # noqa: BLE001 - the binding raises several types
            error: BaseException | None = exc
        else:
            error = None
    if error is not None:
        raise _exr_error(path, error, lines) from None
    return value


def read_exr(path: str | Path) -> np.ndarray:
    """Read an OpenEXR file's RGB(A) channels as float32 (H, W, 3).

    Raises
    ------
    InvalidInputError
        If the file is missing, unreadable or has no RGB / Y channels (one line, with what
        OpenEXR itself printed on stderr folded in).
    """
    path = Path(path)
    if not path.is_file():
        raise InvalidInputError(f"EXR file not found: {path}")

    def read(OpenEXR) -> tuple[np.ndarray | None, list[str]]:
        with OpenEXR.File(str(path), separate_channels=False) as exr:
            channels = exr.channels()
            image = next((np.ascontiguousarray(channels[n].pixels[..., :3], dtype=np.float32)
                          for n in ("RGB", "RGBA") if n in channels), None)
        if image is not None:
            return image, sorted(channels)
        # Separate channels (R, G, B) or a luminance-only file.
        with OpenEXR.File(str(path), separate_channels=True) as exr:
            channels = exr.channels()
            if all(c in channels for c in "RGB"):
                image = np.stack([channels[c].pixels for c in "RGB"], -1).astype(np.float32)
            elif "Y" in channels:
                y = channels["Y"].pixels.astype(np.float32)
                image = np.repeat(y[..., None], 3, axis=-1)
            return image, sorted(channels)

    image, names = _openexr_call(path, read)
    if image is None:
        raise InvalidInputError(f"EXR '{path}' has no RGB or Y channels (has {names})")
    return image


def write_exr(path: str | Path, image: np.ndarray, *, metadata: dict[str, str] | None = None,
              half: bool = False) -> None:
    """Atomically write float32 (H, W, 3) linear RGB to an EXR (ZIP compression).

    ``half`` stores 16-bit floats instead (display-only images: half the bytes).
    """
    import OpenEXR

    image = np.ascontiguousarray(image, dtype=np.float16 if half else np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise InvalidInputError(f"write_exr expects (H, W, 3), got {image.shape}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for key, value in (metadata or {}).items():
        header[key] = str(value)
    with atomic_path(Path(path)) as tmp:
        with OpenEXR.File(header, {"RGB": image}) as exr:
            exr.write(str(tmp))


def read_exr_metadata(path: str | Path) -> dict[str, str]:
    """String attributes of an EXR header (what :func:`write_exr` stored as metadata)."""
    path = Path(path)

    def read(OpenEXR) -> dict[str, str]:
        with OpenEXR.File(str(path)) as exr:
            # Copy inside the block: the binding empties the header when the file closes.
            return {k: v for k, v in exr.header().items() if isinstance(v, str)}

    return _openexr_call(path, read)


def read_hdr(path: str | Path) -> np.ndarray:
    """Read a Radiance RGBE (.hdr/.pic) file, flat or RLE, as float32 (H, W, 3)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InvalidInputError(f"cannot read HDR '{path}': {exc.strerror}") from None
    header_end = data.find(b"\n\n")
    if not data.startswith(b"#?") or header_end < 0:
        raise InvalidInputError(f"'{path}' is not a Radiance HDR file")
    header = data[:header_end].decode("ascii", "replace")
    if "FORMAT=32-bit_rle_xyze" in header:
        raise InvalidInputError(f"HDR '{path}' is XYZE; only RGBE is accepted")
    line_end = data.find(b"\n", header_end + 2)
    m = re.match(r"([-+])Y (\d+) ([-+])X (\d+)", data[header_end + 2:line_end].decode())
    if not m:
        raise InvalidInputError(f"HDR '{path}': unsupported resolution line")
    height, width = int(m.group(2)), int(m.group(4))
    buf = memoryview(data)[line_end + 1:]
    rgbe = np.zeros((height, width, 4), dtype=np.uint8)
    pos = 0
    try:
        for row in range(height):
            if width >= 8 and width < 32768 and buf[pos] == 2 and buf[pos + 1] == 2:
                pos += 4  # new-style RLE scanline: 4 planes, each run-length coded
                for c in range(4):
                    x = 0
                    while x < width:
                        count = buf[pos]
                        pos += 1
                        if count > 128:
                            count -= 128
                            rgbe[row, x:x + count, c] = buf[pos]
                            pos += 1
                        else:
                            rgbe[row, x:x + count, c] = np.frombuffer(buf[pos:pos + count], np.uint8)
                            pos += count
                        x += count
            else:
                rgbe[row] = np.frombuffer(buf[pos:pos + 4 * width], np.uint8).reshape(width, 4)
                pos += 4 * width
    except (IndexError, ValueError):
        raise InvalidInputError(f"HDR '{path}' is truncated or corrupt") from None
    exponent = rgbe[..., 3].astype(np.int32)
    scale = np.where(exponent > 0, np.ldexp(1.0, exponent - 136), 0.0)
    img = rgbe[..., :3].astype(np.float64) * scale[..., None]
    if m.group(1) == "+":
        img = img[::-1]
    return img.astype(np.float32)


def read_hdr_image(path: str | Path) -> np.ndarray:
    """Read an EXR or Radiance HDR environment image by extension."""
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        return read_exr(path)
    if suffix in (".hdr", ".pic", ".rgbe"):
        return read_hdr(path)
    raise InvalidInputError(f"unsupported HDR image '{path}'; accepted: .exr, .hdr, .pic")


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function on linear values (no clipping)."""
    x = np.maximum(np.asarray(x, dtype=np.float64), 0.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def display(hdr: np.ndarray, *, exposure: float = 1.0) -> np.ndarray:
    """Display image of DESIGN.md §7: exposure → sRGB → clip to [0, 1], float32 (H, W, 3)."""
    return np.clip(linear_to_srgb(np.asarray(hdr, np.float64) * exposure), 0.0, 1.0).astype(np.float32)


def png_pixels(image: np.ndarray) -> np.ndarray:
    """The 8-bit pixels :func:`write_png` stores for a [0, 1] float image.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), (H, W, 4) or (H, W)
        Display values; clipped to [0, 1], grey repeated to RGB, alpha dropped.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        ``round(255 · clip(image, 0, 1))`` with NumPy's round-half-to-even.
    """
    img = np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=-1)
    if img.ndim != 3 or img.shape[2] < 3:
        raise InvalidInputError(f"write_png expects (H, W), (H, W, 3) or (H, W, 4), got {img.shape}")
    return np.ascontiguousarray(np.round(img[..., :3] * 255.0).astype(np.uint8))


def write_png(path: str | Path, image: np.ndarray) -> None:
    """Atomically write a [0, 1] float (H, W, 3) or (H, W) image as an 8-bit RGB PNG.

    The pixels are :func:`png_pixels` of ``image``; Pillow encodes them.
    """

    pixels = Image.fromarray(png_pixels(image))
    with atomic_path(Path(path)) as tmp:
        pixels.save(tmp, format="PNG")


def read_png(path: str | Path) -> np.ndarray:
    """Read an 8-bit PNG as float32 [0, 1] (H, W, 3): grey is repeated, alpha dropped.

    Raises
    ------
    InvalidInputError
        If the file is missing or not a readable image.
    """

    try:
        with Image.open(path) as png:
            rgb = np.asarray(png.convert("RGB"))
    except (OSError, UnidentifiedImageError) as exc:
        raise InvalidInputError(f"cannot read PNG '{path}': {exc}") from None
    return rgb.astype(np.float32) / 255.0
