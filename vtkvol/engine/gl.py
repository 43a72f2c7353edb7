"""GL resources that live in VTK's own context: 3D/2D textures, compute programs, mipmaps.

VTK compiles, links and binds (``vtkShaderProgram``, ``vtkTextureObject``); PyOpenGL only issues
the calls VTK has no Python binding for (dispatch, image binding, barriers, mipmap generation,
sub-image uploads). Never call ``glActiveTexture``/``glBindTexture``/``glUseProgram`` here:
``vtkOpenGLState`` caches them (see ../shared/reference/vtk-probe/FINDINGS.md §2–4).

Every function here expects the render window's context to be current; the technique host
(:class:`vtkvol.engine.illuminator.Illuminator`) only calls techniques from the renderer's
``StartEvent``, where it is.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import threading
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
import vtk

# Defined without VTK (engine/errors.py) so the app's dialogs can catch it; re-exported here.
from vtkvol.engine.errors import GLUnavailableError as GLUnavailableError

_GL: Any = None
#: The platforms PyOpenGL can be loaded for: EGL (offscreen, Wayland) and GLX (an X context).
GL_PLATFORMS = ("egl", "glx")
#: Serialises PyOpenGL's first import (:func:`load_in_background` runs it on a worker thread).
_LOAD_LOCK = threading.Lock()
#: The platform chosen by :func:`configure_gl_platform`; None lets the first render window decide.
_PLATFORM: str | None = None


def configure_gl_platform(platform: str) -> None:
    """Load PyOpenGL for ``platform`` (``"egl"`` or ``"glx"``) when :func:`gl` first runs.

    The one place that decides PyOpenGL's platform: the app calls it with the platform of Qt's
    context (GLX under X's ``xcb``, EGL under Wayland), which overrides a ``PYOPENGL_PLATFORM``
    of the environment (a headless habit of EGL would break GLX). PyOpenGL fixes its platform
    at first import, so once :func:`gl` has run another platform is refused.
    """
    global _PLATFORM
    if platform not in GL_PLATFORMS:
        raise ValueError(f"GL platform must be one of {', '.join(GL_PLATFORMS)}, got {platform!r}")
    if _GL is not None and platform != _PLATFORM:
        raise GLUnavailableError(
            f"PyOpenGL is already loaded for {_PLATFORM}; it cannot switch to {platform}")
    _PLATFORM = platform


def gl(render_window: vtk.vtkRenderWindow | None = None) -> Any:
    """PyOpenGL's ``OpenGL.GL`` bound to the platform of ``render_window`` (EGL or GLX).

    The platform is :func:`configure_gl_platform`'s, else ``PYOPENGL_PLATFORM``, else the first
    render window's (EGL for an EGL window or without ``DISPLAY``). PyOpenGL reads the variable
    once, at import, so it is set for that import only: child processes (batch workers) and
    the environment stay as they were. With glvnd both dispatch to whatever context is
    current, which is what VTK made current.
    """
    global _GL, _PLATFORM
    if _GL is not None:
        return _GL
    with _LOAD_LOCK:
        if _GL is not None:  # loaded meanwhile by another thread
            return _GL
        platform = _PLATFORM or os.environ.get("PYOPENGL_PLATFORM")
        if platform is None:
            name = type(render_window).__name__ if render_window is not None else ""
            platform = "egl" if "EGL" in name or not os.environ.get("DISPLAY") else "glx"
        before = os.environ.get("PYOPENGL_PLATFORM")
        os.environ["PYOPENGL_PLATFORM"] = platform
        try:
            from OpenGL import GL
        except Exception as exc:  # ImportError, or a platform that cannot load
            raise GLUnavailableError(f"PyOpenGL could not be loaded: {exc}") from exc
        finally:
            if before is None:
                del os.environ["PYOPENGL_PLATFORM"]
            else:
                os.environ["PYOPENGL_PLATFORM"] = before
        _GL, _PLATFORM = GL, platform
    return _GL


def load_in_background() -> threading.Thread:
    """Start PyOpenGL's first import (:func:`gl`) on a daemon thread and return the thread.

    The import takes about a second of Python on a slow machine, and the first technique to
    need it (the empty-space grid's upload) ran it inside a frame: the app's first frame after
    opening or cropping froze that long (1.75 s measured on the 2-core llvmpipe machine). Call
    it once the platform is known (:func:`configure_gl_platform`). The import needs no GL
    context, and a failure is left for :func:`gl` to report where GL is used.
    """
    def load() -> None:
        with contextlib.suppress(GLUnavailableError):
            gl()

    thread = threading.Thread(target=load, name="vtkvol-pyopengl-import", daemon=True)
    thread.start()
    return thread


def compute_supported(render_window: vtk.vtkRenderWindow) -> bool:
    """True when the (initialised) context can run compute shaders through PyOpenGL."""
    try:
        gl(render_window)
    except GLUnavailableError:
        return False
    # IsComputeShaderSupported() is only meaningful once a context exists (FINDINGS §3).
    return bool(vtk.vtkShader.IsComputeShaderSupported())


class Texture3D:
    """A float 3D texture of 1, 2 or 4 channels (R32F, RG32F, RGBA32F) in VTK's context.

    ``shape`` is (nz, ny, nx) like the numpy arrays it is filled from (``[z, y, x]`` for one
    channel, ``[z, y, x, c]`` for more). Linear filtering, clamp-to-edge (or clamp-to-border
    with ``border``), optional mip chain (single channel).
    """

    _FORMATS: ClassVar[dict[int, tuple[str, str]]] = {
        1: ("GL_R32F", "GL_RED"), 2: ("GL_RG32F", "GL_RG"), 4: ("GL_RGBA32F", "GL_RGBA"),
    }

    def __init__(
        self,
        render_window: vtk.vtkRenderWindow,
        shape_zyx: tuple[int, int, int],
        *,
        data: np.ndarray | None = None,
        mip_levels: int = 1,
        border: float | None = None,
        channels: int = 1,
    ) -> None:
        if channels not in self._FORMATS:
            raise ValueError(f"channels must be 1, 2 or 4, not {channels}")
        if channels > 1 and mip_levels > 1:
            raise ValueError("only single-channel textures have mip levels here")
        self.render_window = render_window
        self.shape = tuple(int(s) for s in shape_zyx)
        self.channels = int(channels)
        self.mip_levels = int(mip_levels)
        tex = vtk.vtkTextureObject()
        tex.SetContext(render_window)
        mip = self.mip_levels > 1
        tex.SetMinificationFilter(
            vtk.vtkTextureObject.LinearMipmapLinear if mip else vtk.vtkTextureObject.Linear
        )
        tex.SetMagnificationFilter(vtk.vtkTextureObject.Linear)
        wrap = vtk.vtkTextureObject.ClampToEdge
        if border is not None:
            wrap = vtk.vtkTextureObject.ClampToBorder
            tex.SetBorderColor(border, border, border, border)
        tex.SetWrapS(wrap)
        tex.SetWrapT(wrap)
        tex.SetWrapR(wrap)
        if mip:
            tex.SetMaxLevel(self.mip_levels - 1)  # default 0 hides the mips (FINDINGS §4)
        nz, ny, nx = self.shape
        if data is None:
            ok = tex.Allocate3D(nx, ny, nz, self.channels, vtk.VTK_FLOAT)
        else:
            arr = self._checked(data)
            ok = tex.Create3DFromRaw(nx, ny, nz, self.channels, vtk.VTK_FLOAT, arr)
        if not ok:
            raise GLUnavailableError(
                f"could not allocate a {nx}×{ny}×{nz}×{self.channels} float 3D texture"
            )
        self.tex = tex

    def _checked(self, data: np.ndarray) -> np.ndarray:
        arr = np.ascontiguousarray(data, dtype=np.float32)
        want = self.shape if self.channels == 1 else (*self.shape, self.channels)
        if arr.shape != want:
            raise ValueError(f"texture data shape {arr.shape} != {want}")
        return arr

    @property
    def gl_format(self) -> int:
        """The sized internal format (``GL_R32F``, ``GL_RG32F`` or ``GL_RGBA32F``)."""
        return getattr(gl(self.render_window), self._FORMATS[self.channels][0])

    @property
    def _pixel_format(self) -> int:
        return getattr(gl(self.render_window), self._FORMATS[self.channels][1])

    @property
    def handle(self) -> int:
        return int(self.tex.GetHandle())

    def activate(self) -> int:
        """Bind to a texture unit reserved by VTK's unit manager; returns the unit."""
        self.tex.Activate()
        return int(self.tex.GetTextureUnit())

    def upload(self, data: np.ndarray, level: int = 0) -> None:
        """Replace the contents of level 0 in place (keeps the texture unit), or (re)specify
        the storage of mip ``level`` > 0 (single channel)."""
        GL = gl(self.render_window)
        arr = self._checked(data) if level == 0 else np.ascontiguousarray(data, np.float32)
        self.tex.Activate()
        state = self.render_window.GetState()
        state.vtkglPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        nz, ny, nx = arr.shape[:3]
        if level == 0:
            GL.glTexSubImage3D(
                GL.GL_TEXTURE_3D, 0, 0, 0, 0, nx, ny, nz, self._pixel_format, GL.GL_FLOAT, arr
            )
        else:
            GL.glTexImage3D(
                GL.GL_TEXTURE_3D, level, GL.GL_R32F, nx, ny, nz, 0, GL.GL_RED, GL.GL_FLOAT, arr
            )

    def upload_slab(self, data: np.ndarray, z0: int) -> None:
        """Replace z slices ``z0…z0 + len(data)`` of level 0 in place (a large upload in
        parts: chunked precomputation)."""
        GL = gl(self.render_window)
        arr = np.ascontiguousarray(data, dtype=np.float32)
        nz, ny, nx = arr.shape[:3]
        if (ny, nx) != tuple(self.shape[1:3]) or not 0 <= z0 <= self.shape[0] - nz:
            raise ValueError(f"slab of shape {arr.shape} at z {z0} does not fit {self.shape}")
        self.tex.Activate()
        self.render_window.GetState().vtkglPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        GL.glTexSubImage3D(GL.GL_TEXTURE_3D, 0, 0, 0, z0, nx, ny, nz, self._pixel_format,
                           GL.GL_FLOAT, arr)

    def clear(self) -> None:
        """Set every texel of level 0 to zero on the GPU (``glClearTexImage``: no upload of a
        zero array — a restart's zeroed state in a fraction of the upload's time)."""
        GL = gl(self.render_window)
        GL.glClearTexImage(self.handle, 0, self._pixel_format, GL.GL_FLOAT, None)

    def copy_to(self, dst: Texture3D, level: int = 0) -> None:
        """Copy level 0 into level ``level`` of ``dst`` (same size there, same channels) on
        the GPU (``glCopyImageSubData``: no binding, no read-back); shader writes issued
        before are made visible first."""
        nz, ny, nx = self.shape
        dz, dy, dx = (max(1, s >> level) for s in dst.shape)
        if (dz, dy, dx) != (nz, ny, nx) or dst.channels != self.channels:
            raise ValueError(f"cannot copy a {self.shape} texture into level {level} of "
                             f"{dst.shape}")
        GL = gl(self.render_window)
        GL.glMemoryBarrier(GL.GL_ALL_BARRIER_BITS)
        GL.glCopyImageSubData(self.handle, GL.GL_TEXTURE_3D, 0, 0, 0, 0, dst.handle,
                              GL.GL_TEXTURE_3D, level, 0, 0, 0, nx, ny, nz)

    def generate_mipmaps(self) -> None:
        """Fill levels 1… from level 0 with the driver's box filter (``mip_levels`` > 1)."""
        if self.mip_levels <= 1:
            raise ValueError("this texture was created without mip levels")
        GL = gl(self.render_window)
        self.tex.Activate()
        GL.glGenerateMipmap(GL.GL_TEXTURE_3D)

    def download(self, level: int = 0) -> np.ndarray:
        """Read back a level (for tests and verification); shape (nz, ny, nx[, channels])."""
        GL = gl(self.render_window)
        self.tex.Activate()
        GL.glFinish()
        nz, ny, nx = (max(1, s >> level) for s in self.shape)
        shape = (nz, ny, nx) if self.channels == 1 else (nz, ny, nx, self.channels)
        out = np.empty(shape, np.float32)
        self.render_window.GetState().vtkglPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glGetTexImage(GL.GL_TEXTURE_3D, level, self._pixel_format, GL.GL_FLOAT, out)
        return out

    def bind_image(self, unit: int, access: str = "write", level: int = 0) -> None:
        """Bind as ``image3D`` on image unit ``unit`` for a compute shader."""
        GL = gl(self.render_window)
        mode = {"read": GL.GL_READ_ONLY, "write": GL.GL_WRITE_ONLY, "readwrite": GL.GL_READ_WRITE}
        GL.glBindImageTexture(
            unit, self.handle, level, GL.GL_TRUE, 0, mode[access], self.gl_format
        )

    def release(self) -> None:
        if self.tex is not None:
            self.tex.Deactivate()
            self.tex.ReleaseGraphicsResources(self.render_window)
            self.tex = None

    @property
    def nbytes(self) -> int:
        nz, ny, nx = self.shape
        total = 0
        for level in range(self.mip_levels):
            total += max(1, nx >> level) * max(1, ny >> level) * max(1, nz >> level) * 4
        return total * self.channels


def linear_texture_2d(render_window: vtk.vtkRenderWindow) -> vtk.vtkTextureObject:
    """A 2-D texture object of ``render_window``'s context, filtered linearly and clamped to
    its edges, not yet allocated (the caller creates its storage)."""
    tex = vtk.vtkTextureObject()
    tex.SetContext(render_window)
    tex.SetMinificationFilter(vtk.vtkTextureObject.Linear)
    tex.SetMagnificationFilter(vtk.vtkTextureObject.Linear)
    tex.SetWrapS(vtk.vtkTextureObject.ClampToEdge)
    tex.SetWrapT(vtk.vtkTextureObject.ClampToEdge)
    return tex


class Texture2D:
    """A small single-channel float 2D texture (lookup tables such as slice weights)."""

    def __init__(self, render_window: vtk.vtkRenderWindow, data: np.ndarray) -> None:
        self.render_window = render_window
        arr = np.ascontiguousarray(data, dtype=np.float32)
        tex = linear_texture_2d(render_window)
        h, w = arr.shape
        if not tex.Create2DFromRaw(w, h, 1, vtk.VTK_FLOAT, arr):
            raise GLUnavailableError(f"could not allocate a {w}×{h} float 2D texture")
        self.shape = arr.shape
        self.tex = tex

    def activate(self) -> int:
        self.tex.Activate()
        return int(self.tex.GetTextureUnit())

    def upload(self, data: np.ndarray) -> None:
        GL = gl(self.render_window)
        arr = np.ascontiguousarray(data, dtype=np.float32)
        if arr.shape != self.shape:
            raise ValueError(f"lookup table shape {arr.shape} != {self.shape}")
        self.tex.Activate()
        self.render_window.GetState().vtkglPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        h, w = arr.shape
        GL.glTexSubImage2D(GL.GL_TEXTURE_2D, 0, 0, 0, w, h, GL.GL_RED, GL.GL_FLOAT, arr)

    def release(self) -> None:
        if self.tex is not None:
            self.tex.Deactivate()
            self.tex.ReleaseGraphicsResources(self.render_window)
            self.tex = None


class StorageBuffer:
    """A GL buffer object used as a shader storage buffer (``std430`` arrays a compute shader
    reads or writes with plain memory loads: on llvmpipe several times cheaper than texel
    fetches and image stores) and as a pixel-unpack source for texture copies on the GPU.

    VTK's state cache does not track these bindings; every method leaves the generic
    ``GL_SHADER_STORAGE_BUFFER`` and ``GL_PIXEL_UNPACK_BUFFER`` bindings at 0."""

    def __init__(self, render_window: vtk.vtkRenderWindow, nbytes: int = 0) -> None:
        self.render_window = render_window
        GL = gl(render_window)
        self.handle: int | None = int(np.asarray(GL.glGenBuffers(1)).ravel()[0])
        self.nbytes = 0
        if nbytes:
            self.allocate(nbytes)

    def _bound(self) -> Any:
        GL = gl(self.render_window)
        if self.handle is None:
            raise GLUnavailableError("the storage buffer was released")
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.handle)
        return GL

    def allocate(self, nbytes: int) -> None:
        """(Re)specify ``nbytes`` of undefined storage."""
        GL = self._bound()
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, int(nbytes), None, GL.GL_DYNAMIC_COPY)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        self.nbytes = int(nbytes)

    def upload(self, data: np.ndarray) -> None:
        """Replace the storage by ``data``'s bytes (C order)."""
        arr = np.ascontiguousarray(data)
        GL = self._bound()
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, arr.nbytes, arr, GL.GL_DYNAMIC_DRAW)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        self.nbytes = int(arr.nbytes)

    def bind(self, binding: int) -> None:
        """Attach to the shader's ``layout(std430, binding = binding)`` block."""
        GL = gl(self.render_window)
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, binding, self.handle)

    @staticmethod
    def unbind(render_window: vtk.vtkRenderWindow, bindings: int) -> None:
        GL = gl(render_window)
        for binding in range(bindings):
            GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, binding, 0)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def copy_to_texture(self, texture: Texture3D, z0: int, slices: int) -> None:
        """Level 0 slices ``z0…z0 + slices`` of the single-channel float ``texture`` from the
        first floats of this buffer (x fastest), on the GPU; shader writes are made visible
        first."""
        GL = gl(self.render_window)
        nz, ny, nx = texture.shape
        if texture.channels != 1 or not 0 <= z0 <= nz - slices or (
                nx * ny * slices * 4 > self.nbytes):
            raise ValueError(f"cannot copy {slices} slices at z {z0} into {texture.shape}")
        GL.glMemoryBarrier(GL.GL_PIXEL_BUFFER_BARRIER_BIT | GL.GL_TEXTURE_UPDATE_BARRIER_BIT)
        texture.tex.Activate()
        self.render_window.GetState().vtkglPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        GL.glBindBuffer(GL.GL_PIXEL_UNPACK_BUFFER, self.handle)
        try:
            GL.glTexSubImage3D(GL.GL_TEXTURE_3D, 0, 0, 0, z0, nx, ny, slices, GL.GL_RED,
                               GL.GL_FLOAT, None)
        finally:
            GL.glBindBuffer(GL.GL_PIXEL_UNPACK_BUFFER, 0)

    def release(self) -> None:
        if self.handle is not None:
            gl(self.render_window).glDeleteBuffers(1, [self.handle])
            self.handle = None
            self.nbytes = 0


class GpuTimer:
    """GPU time of the GL work between :meth:`begin` and :meth:`end`, read without stalling.

    Two ``GL_TIMESTAMP`` queries (``glQueryCounter``) rather than one ``GL_TIME_ELAPSED``
    query: on Mesa llvmpipe the first ``GL_TIME_ELAPSED`` query of a context that has drawn
    nothing yet (a technique's first recompute, issued before the first frame's draw) reports
    the time since boot (measured: 6.6·10⁶ ms for a 19 ms recompute), while timestamps are
    right; timestamps can also bracket work inside another query. :meth:`result_ms` returns
    the milliseconds once the driver has them (``GL_QUERY_RESULT_AVAILABLE``, usually by the
    next frame), else None. Used only when profiling: production frames never wait for the GPU.
    """

    def __init__(self, render_window: vtk.vtkRenderWindow) -> None:
        self.render_window = render_window
        GL = gl(render_window)
        self._queries = [int(q) for q in np.asarray(GL.glGenQueries(2)).ravel()[:2]]
        self._ms: float | None = None
        self._ended = False

    def begin(self) -> None:
        GL = gl(self.render_window)
        GL.glQueryCounter(self._queries[0], GL.GL_TIMESTAMP)

    def end(self) -> None:
        GL = gl(self.render_window)
        GL.glQueryCounter(self._queries[1], GL.GL_TIMESTAMP)
        self._ended = True

    def result_ms(self) -> float | None:
        """GPU milliseconds between begin and end, or None while the driver is not done."""
        if self._ms is None and self._ended and self._queries:
            GL = gl(self.render_window)
            available = GL.glGetQueryObjectiv(self._queries[1], GL.GL_QUERY_RESULT_AVAILABLE)
            if int(np.asarray(available).ravel()[0]):
                # PyOpenGL's wrapper cannot convert 64-bit results: call the raw entry point.
                from OpenGL.raw.GL.VERSION.GL_3_3 import glGetQueryObjectui64v

                stamps = []
                for query in self._queries:  # the end being available implies the begin is
                    ns = ctypes.c_uint64(0)
                    glGetQueryObjectui64v(query, GL.GL_QUERY_RESULT, ctypes.byref(ns))
                    stamps.append(ns.value)
                self._ms = (stamps[1] - stamps[0]) / 1e6
                self.release()
        return self._ms

    def release(self) -> None:
        if self._queries:
            gl(self.render_window).glDeleteQueries(len(self._queries), self._queries)
            self._queries = []


class ComputeProgram:
    """A compute shader compiled and bound by VTK, dispatched by PyOpenGL."""

    def __init__(self, render_window: vtk.vtkRenderWindow, source: str, name: str) -> None:
        self.render_window = render_window
        self.name = name
        if not compute_supported(render_window):
            raise GLUnavailableError("this OpenGL context has no compute shaders")
        prog = vtk.vtkShaderProgram()
        prog.GetComputeShader().SetSource(source)
        cache = render_window.GetShaderCache()
        cache.ReadyShaderProgram(prog)
        if not prog.GetCompiled():
            error = prog.GetError() or "unknown error"
            cache.ReleaseCurrentShader()
            raise GLUnavailableError(f"compute shader {name!r} failed to build:\n{error}")
        cache.ReleaseCurrentShader()
        self.prog = prog
        self._locations: dict[str, int] = {}  # uniform name → location (−1: not in the program)

    def location(self, uniform: str, *, optional: bool = False) -> int:
        """The location of ``uniform`` in this program (cached). A uniform the program does not
        have (misspelt, renamed, or optimised away because unused) is a
        :class:`GLUnavailableError` naming program and uniform, unless ``optional`` (a
        variant of the shader that does not read it): then −1."""
        loc = self._locations.get(uniform)
        if loc is None:
            handle = int(self.prog.GetHandle())
            loc = int(gl(self.render_window).glGetUniformLocation(handle, uniform))
            self._locations[uniform] = loc
        if loc < 0 and not optional:
            raise GLUnavailableError(f"compute shader {self.name!r} has no uniform {uniform!r}")
        return loc

    def set_uniform(self, uniform: str, *values: float, kind: str = "i",
                    optional: bool = False) -> None:
        """Set ``uniform`` of this program, which must be bound (:meth:`use`): one to four
        ``values`` as ``int``/``ivecN`` (``kind`` ``"i"``), ``uint``/``uvecN`` (``"ui"``) or
        ``float``/``vecN`` (``"f"``). Checked: see :meth:`location`."""
        loc = self.location(uniform, optional=optional)
        if loc >= 0:
            getattr(gl(self.render_window), f"glUniform{len(values)}{kind}")(loc, *values)

    def set_uniform_array(self, uniform: str, values: Sequence[float], *, size: int = 1,
                          kind: str = "f", optional: bool = False) -> None:
        """Set the array ``uniform`` (elements of ``size`` components: ``float[n]`` is 1,
        ``vec3[n]`` 3) from the flat ``values``, of ``kind`` ``"f"`` or ``"i"``; checked as
        :meth:`set_uniform`."""
        loc = self.location(uniform, optional=optional)
        if loc >= 0:
            dtype = np.float32 if kind == "f" else np.int32
            flat = np.ascontiguousarray(values, dtype=dtype).ravel()
            getattr(gl(self.render_window), f"glUniform{size}{kind}v")(
                loc, len(flat) // size, flat)

    def use(self) -> vtk.vtkShaderProgram:
        self.render_window.GetShaderCache().ReadyShaderProgram(self.prog)
        return self.prog

    def dispatch(self, groups: tuple[int, int, int], barrier: bool = True) -> None:
        GL = gl(self.render_window)
        GL.glDispatchCompute(*(max(1, int(g)) for g in groups))
        if barrier:
            GL.glMemoryBarrier(
                GL.GL_TEXTURE_FETCH_BARRIER_BIT | GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT
            )

    def done(self) -> None:
        self.render_window.GetShaderCache().ReleaseCurrentShader()

    def release(self) -> None:
        self._locations.clear()
        if self.prog is not None:
            self.prog.ReleaseGraphicsResources(self.render_window)
            self.prog = None
            # ReleaseGraphicsResources() always calls glUseProgram(0) but tells the shader
            # cache only if this program was its last bound one; otherwise the cache still
            # believes the ray caster's program is bound and the next frame draws with
            # program 0 (a blank volume). Resync the cache.
            self.render_window.GetShaderCache().ReleaseCurrentShader()


def unbind_images(render_window: vtk.vtkRenderWindow, units: int) -> None:
    """Detach image units 0…``units``−1 after a dispatch (a texture left bound there stays
    referenced by the context, and a later dispatch of another program could write it)."""
    GL = gl(render_window)
    for unit in range(units):
        GL.glBindImageTexture(unit, 0, 0, GL.GL_FALSE, 0, GL.GL_READ_ONLY, GL.GL_R32F)
