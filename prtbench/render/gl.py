"""OpenGL through moderngl on a headless EGL context (DESIGN.md §9).

One process-wide context (Mesa llvmpipe on CPU machines, the NVIDIA driver on GPU machines),
float32 render targets without MSAA for metric renders, GLSL programs loaded from the core's
``prtbench/render/shaders`` plus the folders a caller passes (a method's own ``shaders/``), with
``#include`` and injected ``#define``\\ s, mesh upload, and GPU timer queries. Images read
back from a :class:`RenderTarget` are (H, W, 4) float32 with row 0 at the top, like every other
image in prtbench.
"""

from __future__ import annotations

import re
import statistics
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError


def _moderngl():
    """moderngl, imported on first GL use so importing a method's module (e.g. for its summary
    in ``prtbench list methods``) stays free of it; None when it is not installed."""
    try:
        import moderngl
    except ImportError:  # create_context reports it with the install hint
        return None
    return moderngl


def __getattr__(name: str):
    # ``gl.moderngl`` stays usable for its constants (DEPTH_TEST, TRIANGLES, ...), lazily.
    if name == "moderngl":
        return _moderngl()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


_MESA_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"
_context = None
_context_lock = threading.Lock()

#: GL versions asked for in order: 4.3 gives compute shaders and SSBOs; 3.3 core is the floor.
#: Drivers answer a request with the newest compatible core version they have.
_GL_VERSIONS = (430, 330)


class GLUnavailableError(PrtbenchError):
    """No OpenGL ≥ 3.3 context could be created through EGL."""


def create_context():
    """The process-wide headless OpenGL context (moderngl, EGL backend).

    Asks for GL 4.3 or newer and falls back to the highest version ≥ 3.3 the driver gives.

    Returns
    -------
    moderngl.Context

    Raises
    ------
    GLUnavailableError
        If moderngl or an EGL driver is missing, naming the packages to install.
    """
    global _context
    with _context_lock:
        if _context is not None:
            return _context
        moderngl = _moderngl()
        if moderngl is None:
            raise GLUnavailableError("moderngl is not installed; pip install moderngl")
        first_error = None
        for version in _GL_VERSIONS:
            try:
                _context = moderngl.create_standalone_context(backend="egl", require=version)
                return _context
            except Exception as exc:  # noqa: BLE001 - glcontext raises plain Exceptions
                first_error = first_error or exc
        detail = " ".join(str(first_error).split())
        raise GLUnavailableError(
            "cannot create a headless OpenGL >= 3.3 context through EGL; install Debian packages "
            f"{_MESA_PACKAGES} (Mesa) or the NVIDIA driver's EGL vendor library on GPU machines "
            f"(error: {detail})")


def renderer_string(ctx=None) -> str:
    """``GL_RENDERER / GL_VERSION`` of ``ctx`` (default: the process context), for every timing."""
    ctx = ctx or create_context()
    return f"{ctx.info['GL_RENDERER']} / {ctx.info['GL_VERSION']}"


def storage_block_limit(ctx=None) -> int:
    """``GL_MAX_SHADER_STORAGE_BLOCK_SIZE`` in bytes of ``ctx`` (default: the process context),
    0 if the driver does not say. Mesa llvmpipe reports 128 MiB; NVIDIA about 2 GiB."""
    ctx = ctx or create_context()
    return int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 0) or 0)


class RenderTarget:
    """A framebuffer of RGBA32F colour attachments and a 24-bit depth texture, no MSAA.

    Parameters
    ----------
    ctx : moderngl.Context
    width, height : int
        Size in pixels.
    attachments : int
        Number of colour attachments (fragment outputs ``layout(location = i)``).

    Attributes
    ----------
    textures : list of moderngl.Texture
        The colour attachments (nearest filtering).
    depth : moderngl.Texture
        The depth attachment, usable for a depth pre-pass or sampling.
    fbo : moderngl.Framebuffer
    """

    def __init__(self, ctx, width: int, height: int, *, attachments: int = 1):
        max_attachments = int(ctx.info.get("GL_MAX_COLOR_ATTACHMENTS", 8))
        if int(width) != width or int(height) != height or width < 1 or height < 1:
            raise InvalidInputError(f"render target size {width}x{height}; accepted: positive integers")
        if int(attachments) != attachments or not 1 <= attachments <= max_attachments:
            raise InvalidInputError(
                f"render target attachments={attachments!r}; accepted: 1..{max_attachments}")
        self.ctx, self.width, self.height = ctx, int(width), int(height)
        size = (self.width, self.height)
        self.textures = [ctx.texture(size, 4, dtype="f4") for _ in range(int(attachments))]
        for tex in self.textures:
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
        # A depth texture rather than a renderbuffer so a pre-pass's depth can also be sampled.
        self.depth = ctx.depth_texture(size)
        self.fbo = ctx.framebuffer(color_attachments=self.textures, depth_attachment=self.depth)

    def use(self) -> None:
        """Bind as the draw framebuffer (also sets the viewport to the full target)."""
        self.fbo.use()
        self.ctx.viewport = (0, 0, self.width, self.height)

    def clear(self, color: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)) -> None:
        """Clear every colour attachment to ``color`` and depth to 1."""
        self.fbo.clear(*color, depth=1.0)

    def read(self, attachment: int = 0) -> np.ndarray:
        """Read one colour attachment back.

        Returns
        -------
        ndarray, shape (height, width, 4), float32
            Row 0 is the top of the image (GL's bottom-up rows are flipped).
        """
        if not 0 <= attachment < len(self.textures):
            raise InvalidInputError(
                f"attachment {attachment}; accepted: 0..{len(self.textures) - 1}")
        raw = self.fbo.read(components=4, attachment=attachment, dtype="f4", alignment=1)
        image = np.frombuffer(raw, dtype=np.float32).reshape(self.height, self.width, 4)
        return np.ascontiguousarray(image[::-1])

    def release(self) -> None:
        """Free the GL objects."""
        self.fbo.release()
        for tex in self.textures:
            tex.release()
        self.depth.release()
        self.textures = []

    def __enter__(self) -> "RenderTarget":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


# --------------------------------------------------------------------------------- shaders


#: The core's GLSL (SH, BRDF, PRT shading, SDF tracing), package data of prtbench. The core never
#: looks into a plug-in's folder: a method passes its own through ``search_path``.
CORE_SHADER_DIR = Path(__file__).resolve().parent / "shaders"


def shader_dir() -> Path:
    """``prtbench/render/shaders``: the core's stage files and includes, always searched last."""
    return CORE_SHADER_DIR


_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
_VERSION = re.compile(r"^\s*#\s*version\b")


def _find_shader(name: str | Path, dirs: Sequence[Path]) -> Path:
    candidate = Path(name)
    if candidate.is_absolute():
        if candidate.is_file():
            return candidate
        raise InvalidInputError(f"shader file not found: {candidate}")
    for directory in dirs:
        for path in (directory / candidate, directory / f"{candidate}.glsl"):
            if path.is_file():
                return path.resolve()
    known = sorted({p.name for d in dirs if d.is_dir() for p in d.glob("*.glsl")})
    raise UnknownNameError("shader", str(name), known)


class _Source:
    """One stage's expanded source; maps GLSL source-string numbers back to file names."""

    def __init__(self, files: list[Path]):
        self.files = files  # shared across the stages of a program: ids are program-unique
        self.included: set[Path] = set()

    def file_id(self, path: Path) -> int:
        if path not in self.files:
            self.files.append(path)
        return self.files.index(path)

    def expand(self, path: Path, dirs: Sequence[Path], lines_out: list[str]) -> None:
        self.included.add(path)
        fid = self.file_id(path)
        for number, line in enumerate(path.read_text().splitlines(), start=1):
            match = _INCLUDE.match(line)
            if not match:
                lines_out.append(line)
                continue
            target = _find_shader(match.group(1), [path.parent, *dirs])
            if target in self.included:  # included once per stage, like #pragma once
                lines_out.append(f"// {match.group(1)} already included")
                continue
            lines_out.append(f"#line 1 {self.file_id(target)}")
            self.expand(target, dirs, lines_out)
            # GLSL: the line after `#line N` is line N (Mesa and the spec agree).
            lines_out.append(f"#line {number + 1} {fid}")


def _stage_source(name, dirs, defines, files) -> str:
    path = _find_shader(name, dirs)
    lines: list[str] = []
    _Source(files).expand(path, dirs, lines)
    version_at = next((i for i, line in enumerate(lines) if _VERSION.match(line)), None)
    if version_at is None:
        raise InvalidInputError(f"shader '{path.name}' has no #version line (GLSL 330+ required)")
    injected = [f"#define {key} {_define_value(value)}" for key, value in (defines or {}).items()]
    # Always restate the source-string number: without it the second stage's lines read as 0.
    lines[version_at + 1:version_at + 1] = injected + [f"#line {version_at + 2} {files.index(path)}"]
    return "\n".join(lines) + "\n"


def _define_value(value: object) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if "." in repr(value) or "e" in repr(value) else f"{value}.0"
    return str(value)


_ERROR_LINE = (
    re.compile(r"^\s*(\d+):(\d+)\(\d+\):\s*(.*)$"),  # Mesa: 0:12(5): error: ...
    re.compile(r"^\s*(\d+)\((\d+)\)\s*:\s*(.*)$"),  # NVIDIA: 0(12) : error C0000: ...
)


def _compile_error_message(log: str, files: list[Path], stage_files: list[Path]) -> str:
    lines = [line.strip() for line in log.splitlines() if line.strip()]
    for line in lines:
        for pattern in _ERROR_LINE:
            match = pattern.match(line)
            if match and "error" in match.group(3).lower():
                fid, number, text = int(match.group(1)), int(match.group(2)), match.group(3)
                name = files[fid].name if fid < len(files) else "?"
                return f"GLSL error in shader '{name}' line {number}: {text}"
    first = next((line for line in lines if "error" in line.lower()), lines[-1] if lines else log)
    what = "link" if "Linker" in log else "compile"
    return f"GLSL {what} error in {', '.join(repr(p.name) for p in stage_files)}: {first}"


def load_program(ctx, vertex: str | Path, fragment: str | Path, *,
                 defines: Mapping[str, object] | None = None, geometry: str | Path | None = None,
                 search_path: Sequence[str | Path] = (),
                 sources: Mapping[str, str] | None = None):
    """Compile and link a program from GLSL stage files.

    Stage files are looked up as ``<dir>/<name>`` or ``<dir>/<name>.glsl`` in ``search_path``
    (a method passes its own shader folder) and then the core's ``prtbench/render/shaders``, so a
    method's shaders can ``#include "sh.glsl"``, ``"prt_shading.glsl"`` or ``"sdf_trace.glsl"``.
    ``#include "file.glsl"`` lines are resolved recursively (relative to the including file
    first, then along the same folders), each file at most once per stage; they are resolved
    textually, before the GLSL preprocessor, so an ``#include`` inside ``#if`` is always taken.
    ``defines`` become ``#define KEY VALUE`` lines right after ``#version``; ``#line`` directives
    keep compiler line numbers pointing into the original files.

    ``sources`` maps plain file names to GLSL text: virtual files for code generated at run time
    (e.g. an SDF scene's ``scene_sdf.glsl``), usable as stage files or includes and searched
    before ``search_path`` (an include is still looked up beside its including file first).

    Returns
    -------
    moderngl.Program

    Raises
    ------
    UnknownNameError
        For a missing stage or include file.
    PrtbenchError
        On compile or link errors, naming the shader file and the first error line.
    """
    if sources:
        # Materialised in a private directory for the duration of the build, so the include
        # resolution, #line numbering and error messages work unchanged.
        with tempfile.TemporaryDirectory(prefix="prtbench-glsl-") as tmp:
            for name, text in sources.items():
                if not name or Path(name).name != name:
                    raise InvalidInputError(f"virtual shader name {name!r}; accepted: a plain "
                                            "file name such as 'scene_sdf.glsl'")
                (Path(tmp) / name).write_text(text)
            return load_program(ctx, vertex, fragment, defines=defines, geometry=geometry,
                                search_path=[tmp, *search_path])
    dirs = [Path(d) for d in search_path] + [CORE_SHADER_DIR]
    files: list[Path] = []
    stages = {"vertex_shader": vertex, "fragment_shader": fragment, "geometry_shader": geometry}
    sources = {key: _stage_source(name, dirs, defines, files)
               for key, name in stages.items() if name is not None}
    stage_files = [_find_shader(name, dirs) for name in stages.values() if name is not None]
    try:
        return ctx.program(**sources)
    except _moderngl().Error as exc:
        raise PrtbenchError(_compile_error_message(str(exc), files, stage_files)) from None


# ---------------------------------------------------------------------------------- meshes


def upload_mesh(ctx, program, positions: np.ndarray, faces: np.ndarray, *,
                attributes: Mapping[str, np.ndarray] | None = None,
                position_name: str = "in_position"):
    """Upload an indexed triangle mesh as a vertex array bound to ``program``'s inputs.

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
        Bound to the vertex input ``position_name``.
    faces : ndarray, shape (F, 3), int
        Vertex indices, counter-clockwise front faces.
    attributes : dict of str to ndarray, shape (V, k)
        Extra per-vertex float32 attributes keyed by the GLSL input name (k = 1…4, or 16 for a
        mat4). Inputs the program does not have are skipped: GLSL drops unused inputs.

    Returns
    -------
    moderngl.VertexArray
        Its ``extra`` is ``{"buffers": [...], "bytes": int}`` (vertex + index buffer bytes).
    """
    positions = np.asarray(positions)
    faces = np.asarray(faces)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise InvalidInputError(f"mesh positions shape {positions.shape}; accepted: (V, 3)")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InvalidInputError(f"mesh faces shape {faces.shape}; accepted: (F, 3) with F > 0")
    n_vertices = len(positions)
    if faces.min() < 0 or faces.max() >= n_vertices:
        raise InvalidInputError(f"mesh face indices span {faces.min()}..{faces.max()}; "
                                f"accepted: 0..{n_vertices - 1}")
    inputs = {position_name: positions, **(attributes or {})}
    attribute_type = _moderngl().Attribute
    bindings, buffers = [], []
    for name, values in inputs.items():
        member = program.get(name, None)
        if not isinstance(member, attribute_type):  # absent, or a uniform of that name
            continue
        values = np.asarray(values, dtype=np.float32)
        values = values.reshape(len(values), -1)
        if len(values) != n_vertices:
            raise InvalidInputError(
                f"vertex attribute '{name}' has {len(values)} rows; accepted: {n_vertices} (one per vertex)")
        buffer = ctx.buffer(np.ascontiguousarray(values).tobytes())
        buffers.append(buffer)
        bindings.append((buffer, f"{values.shape[1]}f", name))
    index_buffer = ctx.buffer(np.ascontiguousarray(faces, dtype=np.uint32).tobytes())
    buffers.append(index_buffer)
    try:
        vao = ctx.vertex_array(program, bindings, index_buffer=index_buffer, index_element_size=4)
    except Exception as exc:  # noqa: BLE001 - moderngl reports format mismatches as Error/KeyError
        for buffer in buffers:
            buffer.release()
        raise InvalidInputError(f"cannot bind mesh attributes to the program: {exc}") from None
    vao.extra = {"buffers": buffers, "bytes": sum(b.size for b in buffers)}
    return vao


# ---------------------------------------------------------------------------------- timing


@dataclass(frozen=True)
class FrameTimes:
    """Frame times of one measured draw, milliseconds.

    ``source`` says what was measured: ``"timer-query"`` (GL_TIME_ELAPSED, hardware GPUs) or
    ``"wall+finish"`` (host wall clock around draw + glFinish, used on software rasterisers,
    whose timer queries close before the deferred rasterisation threads finish: on llvmpipe a
    query read 14.5 ms for a draw that took 200 ms).
    """

    median_ms: float
    p95_ms: float
    mean_ms: float
    samples_ms: list[float] = field(default_factory=list)
    source: str = "timer-query"


SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe")


def is_software_renderer(ctx=None) -> bool:
    """True on Mesa's CPU rasterisers, whose timer queries do not cover the raster work."""
    return any(name in renderer_string(ctx).lower() for name in SOFTWARE_RENDERERS)


class GpuTimer:
    """Times draws with GL timer queries (``GL_TIME_ELAPSED``), never the first frame."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._query = ctx.query(time=True)
        self.source = "wall+finish" if is_software_renderer(ctx) else "timer-query"

    def time_frames(self, draw: Callable[[], None], *, warmup: int = 5, frames: int = 30) -> FrameTimes:
        """Run ``draw`` ``warmup`` times untimed, then time it ``frames`` times.

        ``ctx.finish()`` separates frames so no frame's work overlaps the next query; readback
        belongs outside ``draw`` and is never timed.
        """
        if int(warmup) != warmup or warmup < 1:
            raise InvalidInputError(f"warmup={warmup!r}; accepted: integers >= 1 (the first frame is never timed)")
        if int(frames) != frames or frames < 1:
            raise InvalidInputError(f"frames={frames!r}; accepted: integers >= 1")
        for _ in range(int(warmup)):
            draw()
        self.ctx.finish()
        samples = []
        for _ in range(int(frames)):
            start = time.perf_counter()
            with self._query:
                draw()
            self.ctx.finish()
            wall_ms = (time.perf_counter() - start) * 1e3
            samples.append(wall_ms if self.source == "wall+finish" else self._query.elapsed / 1e6)
        ordered = sorted(samples)
        p95 = float(np.percentile(ordered, 95))
        return FrameTimes(median_ms=float(statistics.median(ordered)), p95_ms=p95,
                          mean_ms=float(statistics.fmean(ordered)), samples_ms=samples,
                          source=self.source)

    def release(self) -> None:
        """Drop the query object (moderngl 5.13 Query has no release(): the context frees it)."""
        self._query = None
