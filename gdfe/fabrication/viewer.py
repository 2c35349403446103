"""An interactive 3-D view of a simulated shape: one self-contained, offline HTML page.

The page carries the film's boundary surface (:func:`gdfe.fabrication.hex_surface`) in
every frame of the contraction ramp, and a small viewer written for it (WebGL, with a
canvas-2D painter's-algorithm fallback where WebGL is not available): drag to turn the
shape, wheel or pinch to zoom, and a slider over the activation (0: the flat print, 1: the
fully contracted shape) that interpolates linearly between the frames; *play* runs the
ramp. Faces are coloured by material (:data:`gdfe.io.MATERIAL_COLOURS`). Nothing is loaded
from the network: the data are base64-encoded arrays inside the page.

When the first picture is drawn the page sets ``data-rendered`` on its viewer element to
``webgl`` or ``canvas2d`` (``data-error`` if drawing failed), so that a headless browser can
tell it ran.
"""

from __future__ import annotations

import base64
import html
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from gdfe._validation import GdfeError, check_file

__all__ = ["ViewData", "view_data", "read_series", "viewer_fragment", "viewer_page", "write_viewer"]


class ViewData:
    """What the viewer shows: a surface in several frames.

    Parameters
    ----------
    frames : (f, v, 3) float array [mm]
        Surface vertices in each frame.
    activation : (f,) float array
        Activation of each frame, increasing.
    quads : (q, 4) int array
        Surface quadrilaterals (outward).
    material : (q,) int array
    title : str
    info : dict
        Lines shown under the view (``name -> value``).
    """

    def __init__(self, frames, activation, quads, material, title="gdfe", info=None):
        self.frames = np.asarray(frames, np.float32)
        self.activation = np.asarray(activation, float)
        self.quads = np.asarray(quads, np.uint32)
        self.material = np.asarray(material, np.uint8)
        self.title = str(title)
        self.info = dict(info or {})
        f = len(self.frames)
        if self.frames.ndim != 3 or self.frames.shape[2] != 3 or f == 0:
            raise GdfeError(f"frames: expected an array of shape (f, v, 3), got {self.frames.shape}")
        if self.activation.shape != (f,) or np.any(np.diff(self.activation) < 0):
            raise GdfeError(f"activation: expected {f} non-decreasing values, got {self.activation.tolist()}")
        if self.quads.ndim != 2 or self.quads.shape[1] != 4 or self.material.shape != (len(self.quads),):
            raise GdfeError(f"quads, material: expected shapes (q, 4) and (q,), got {self.quads.shape} "
                            f"and {self.material.shape}")

    def payload(self) -> dict:
        from gdfe.design import Material
        from gdfe.io import MATERIAL_COLOURS

        def b64(a):
            return base64.b64encode(np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()).decode()

        return {"title": self.title, "activation": self.activation.tolist(), "n_frames": len(self.frames),
                "n_vertices": int(self.frames.shape[1]), "n_quads": len(self.quads),
                "frames": b64(self.frames), "quads": b64(self.quads), "material": b64(self.material),
                "colours": MATERIAL_COLOURS.tolist(), "names": [m.name.lower() for m in Material],
                "info": {k: str(v) for k, v in self.info.items()}}


def view_data(result, title=None, info=None):
    """The :class:`ViewData` of a :class:`gdfe.Result` (every frame of its ramp)."""
    from gdfe.fabrication.surface import hex_surface

    design = result.design
    surf = hex_surface(result.frames[0], design.mesh.cells, design.material)
    frames = np.stack([np.asarray(p, float)[surf.point_index] for p in result.frames])
    base = {"cells": design.n_cells, "frames": len(frames),
            "solver": f"{'converged' if result.converged else 'NOT CONVERGED'}, {result.iterations} iterations, "
                      f"residual {result.residual:.1e}"}
    return ViewData(frames, result.activation, surf.quads, surf.material, title=title or "gdfe shape",
                    info={**base, **(info or {})})


def read_series(pvd):
    """Read a VTU series written by :func:`gdfe.io.write_series` back as :class:`ViewData`.

    Parameters
    ----------
    pvd : str or Path
        The ``.pvd`` collection file.
    """
    from gdfe.fabrication.surface import hex_surface
    from gdfe.io import read_mesh

    pvd = check_file("series", pvd, suffixes=(".pvd",), what="ParaView collection")
    try:
        root = ET.parse(pvd).getroot()
    except ET.ParseError as exc:
        raise GdfeError(f"{pvd.name}: not well-formed XML at line {exc.position[0]}, column {exc.position[1]}") from None
    sets = root.findall("./Collection/DataSet")
    if not sets:
        raise GdfeError(f"{pvd.name}: expected <DataSet> entries in a <Collection>, got none")
    entries = []
    for k, ds in enumerate(sets):
        try:
            t = float(ds.get("timestep"))
        except (TypeError, ValueError):
            raise GdfeError(f"{pvd.name}: DataSet {k}: expected a numeric timestep, got {ds.get('timestep')!r}") from None
        f = ds.get("file")
        if not f or not (pvd.parent / f).is_file():
            raise GdfeError(f"{pvd.name}: DataSet {k}: file {f!r} not found beside it")
        entries.append((t, pvd.parent / f))
    entries.sort(key=lambda e: e[0])
    first = read_mesh(entries[0][1], "a VTU frame gdfe wrote")
    cells = first.get_cells_type("hexahedron")
    if not len(cells):
        raise GdfeError(f"{entries[0][1].name}: expected hexahedral cells, got {[c.type for c in first.cells]}")
    mat = first.get_cell_data("material", "hexahedron") if "material" in first.cell_data else np.zeros(len(cells))
    surf = hex_surface(first.points, cells, mat)
    frames = []
    for _, f in entries:
        m = first if f == entries[0][1] else read_mesh(f, "a VTU frame gdfe wrote")
        if m.points.shape != first.points.shape:
            raise GdfeError(f"{f.name}: expected {len(first.points)} points like the first frame, got {len(m.points)}")
        frames.append(np.asarray(m.points, float)[surf.point_index])
    return ViewData(np.stack(frames), [e[0] for e in entries], surf.quads, surf.material, title=pvd.stem,
                    info={"cells": len(cells), "frames": len(frames), "series": pvd.name})


_CSS = """
.gdfe-viewer { font-family: sans-serif; color: #222; max-width: 960px; }
.gdfe-viewer canvas { width: 100%; height: 560px; border: 1px solid #ccc; background: #fff; touch-action: none;
  display: block; cursor: grab; }
.gdfe-viewer .controls { display: flex; align-items: center; gap: .8em; margin: .5em 0; flex-wrap: wrap; }
.gdfe-viewer input[type=range] { flex: 1; min-width: 200px; }
.gdfe-viewer .legend span { display: inline-block; width: .9em; height: .9em; margin: 0 .25em 0 .8em;
  vertical-align: middle; border: 1px solid #888; }
.gdfe-viewer .info { color: #555; font-size: .85em; }
"""

# The viewer: decode the arrays, interpolate the frame, draw with WebGL (or canvas 2D).
_JS = r"""
(function () {
  function decode(b64, Type) {
    var s = atob(b64), n = s.length, bytes = new Uint8Array(n);
    for (var i = 0; i < n; i++) bytes[i] = s.charCodeAt(i);
    return new Type(bytes.buffer);
  }
  function mat4mul(a, b) {
    var o = new Float32Array(16);
    for (var i = 0; i < 4; i++) for (var j = 0; j < 4; j++) {
      var s = 0; for (var k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k]; o[i * 4 + j] = s;
    }
    return o;
  }
  window.gdfeViewer = function (root, data) {
    var canvas = root.querySelector("canvas"), slider = root.querySelector("input[type=range]");
    var label = root.querySelector(".activation"), play = root.querySelector("button");
    var F = data.n_frames, V = data.n_vertices, Q = data.n_quads;
    var frames = decode(data.frames, Float32Array), quads = decode(data.quads, Uint32Array);
    var mats = decode(data.material, Uint8Array), act = data.activation;
    // bounding box of every frame: the camera does not jump along the ramp
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (var i = 0; i < frames.length; i += 3) for (var c = 0; c < 3; c++) {
      lo[c] = Math.min(lo[c], frames[i + c]); hi[c] = Math.max(hi[c], frames[i + c]);
    }
    var centre = [0, 1, 2].map(function (c) { return (lo[c] + hi[c]) / 2; });
    var radius = Math.max(1e-9, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    var T = Q * 2, pos = new Float32Array(T * 9), nrm = new Float32Array(T * 9), col = new Float32Array(T * 9);
    var cur = new Float32Array(V * 3);
    for (var q = 0; q < Q; q++) {
      var rgb = data.colours[mats[q]] || [0.5, 0.5, 0.5];
      for (var k = 0; k < 6; k++) col.set(rgb, (q * 6 + k) * 3);
    }
    var view = { yaw: -0.6, pitch: 0.55, dist: 2.5, a: 1 };
    function setActivation(a) {
      view.a = a;
      var k = 0;
      while (k < F - 2 && act[k + 1] < a) k++;
      var k1 = Math.min(k + 1, F - 1), span = act[k1] - act[k];
      var t = span > 0 ? Math.min(1, Math.max(0, (a - act[k]) / span)) : 0;
      var A = k * V * 3, B = k1 * V * 3;
      for (var i = 0; i < V * 3; i++) cur[i] = frames[A + i] + t * (frames[B + i] - frames[A + i]);
      var tri = [[0, 1, 2], [0, 2, 3]];
      for (var q = 0; q < Q; q++) for (var h = 0; h < 2; h++) {
        var o = (q * 2 + h) * 9, idx = tri[h];
        for (var m = 0; m < 3; m++) {
          var v = quads[q * 4 + idx[m]] * 3;
          pos[o + m * 3] = cur[v] - centre[0]; pos[o + m * 3 + 1] = cur[v + 1] - centre[1];
          pos[o + m * 3 + 2] = cur[v + 2] - centre[2];
        }
        var ux = pos[o + 3] - pos[o], uy = pos[o + 4] - pos[o + 1], uz = pos[o + 5] - pos[o + 2];
        var wx = pos[o + 6] - pos[o], wy = pos[o + 7] - pos[o + 1], wz = pos[o + 8] - pos[o + 2];
        var nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
        var l = Math.hypot(nx, ny, nz) || 1;
        for (var m = 0; m < 3; m++) { nrm[o + m * 3] = nx / l; nrm[o + m * 3 + 1] = ny / l; nrm[o + m * 3 + 2] = nz / l; }
      }
      label.textContent = "activation " + a.toFixed(3) + "  (frames " + k + "-" + k1 + " of " + (F - 1) + ")";
    }
    function matrices() {
      var w = canvas.width, h = canvas.height, asp = w / Math.max(1, h);
      var cy = Math.cos(view.yaw), sy = Math.sin(view.yaw), cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
      var s = 1 / radius;
      // yaw turns about z; the eye is raised by the pitch: x' = cy x + sy y, with u = -sy x + cy y,
      // y' = sp u + cp z (up on the screen), z' = -cp u + sp z (towards the eye); column-major
      var R = new Float32Array([cy * s, -sp * sy * s, cp * sy * s, 0, sy * s, sp * cy * s, -cp * cy * s, 0,
                                0, cp * s, sp * s, 0, 0, 0, -view.dist, 1]);
      var f = 1 / Math.tan(0.3), n = 0.05, fa = 100;
      var P = new Float32Array([f / asp, 0, 0, 0, 0, f, 0, 0, 0, 0, (fa + n) / (n - fa), -1, 0, 0, 2 * fa * n / (n - fa), 0]);
      return { mv: R, mvp: mat4mul(P, R) };
    }
    var gl = null;
    try { gl = canvas.getContext("webgl", { antialias: true }) || canvas.getContext("experimental-webgl"); }
    catch (e) { gl = null; }
    var draw;
    if (gl) {
      var vs = "attribute vec3 p; attribute vec3 n; attribute vec3 c; uniform mat4 mvp; uniform mat4 mv;" +
               "varying vec3 vc; varying vec3 vn; void main() { gl_Position = mvp * vec4(p, 1.0);" +
               "vn = (mv * vec4(n, 0.0)).xyz; vc = c; }";
      var fs = "precision mediump float; varying vec3 vc; varying vec3 vn; void main() {" +
               "vec3 L = normalize(vec3(0.3, 0.5, 1.0)); float d = abs(dot(normalize(vn), L));" +
               "gl_FragColor = vec4(vc * (0.35 + 0.65 * d), 1.0); }";
      function shader(type, src) {
        var s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
        if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
        return s;
      }
      var prog = gl.createProgram();
      gl.attachShader(prog, shader(gl.VERTEX_SHADER, vs)); gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, fs));
      gl.linkProgram(prog); gl.useProgram(prog);
      var bufs = {};
      ["p", "n", "c"].forEach(function (name) {
        bufs[name] = gl.createBuffer(); var loc = gl.getAttribLocation(prog, name);
        gl.bindBuffer(gl.ARRAY_BUFFER, bufs[name]); gl.enableVertexAttribArray(loc);
        gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
      });
      gl.bindBuffer(gl.ARRAY_BUFFER, bufs.c); gl.bufferData(gl.ARRAY_BUFFER, col, gl.STATIC_DRAW);
      gl.enable(gl.DEPTH_TEST);
      draw = function () {
        var m = matrices();
        gl.viewport(0, 0, canvas.width, canvas.height); gl.clearColor(1, 1, 1, 1);
        gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
        gl.bindBuffer(gl.ARRAY_BUFFER, bufs.p); gl.bufferData(gl.ARRAY_BUFFER, pos, gl.DYNAMIC_DRAW);
        gl.bindBuffer(gl.ARRAY_BUFFER, bufs.n); gl.bufferData(gl.ARRAY_BUFFER, nrm, gl.DYNAMIC_DRAW);
        gl.uniformMatrix4fv(gl.getUniformLocation(prog, "mvp"), false, m.mvp);
        gl.uniformMatrix4fv(gl.getUniformLocation(prog, "mv"), false, m.mv);
        gl.drawArrays(gl.TRIANGLES, 0, T * 3);
      };
      root.dataset.mode = "webgl";
    } else {
      var ctx = canvas.getContext("2d"), order = new Uint32Array(T), depth = new Float32Array(T);
      var sx = new Float32Array(T * 3), syy = new Float32Array(T * 3);
      draw = function () {
        var m = matrices(), M = m.mvp, w = canvas.width, h = canvas.height;
        ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, w, h);
        for (var t = 0; t < T; t++) {
          var z = 0;
          for (var k = 0; k < 3; k++) {
            var o = t * 9 + k * 3, x = pos[o], y = pos[o + 1], zz = pos[o + 2];
            var X = M[0] * x + M[4] * y + M[8] * zz + M[12], Y = M[1] * x + M[5] * y + M[9] * zz + M[13];
            var W = M[3] * x + M[7] * y + M[11] * zz + M[15], Z = M[2] * x + M[6] * y + M[10] * zz + M[14];
            sx[t * 3 + k] = (X / W * 0.5 + 0.5) * w; syy[t * 3 + k] = (0.5 - Y / W * 0.5) * h; z += Z / W;
          }
          depth[t] = z; order[t] = t;
        }
        var ord = Array.prototype.slice.call(order).sort(function (a, b) { return depth[b] - depth[a]; });
        var mv = m.mv, L = [0.3, 0.5, 1.0], ll = Math.hypot(L[0], L[1], L[2]);
        for (var i = 0; i < T; i++) {
          var t = ord[i], o = t * 9;
          var nx = mv[0] * nrm[o] + mv[4] * nrm[o + 1] + mv[8] * nrm[o + 2];
          var ny = mv[1] * nrm[o] + mv[5] * nrm[o + 1] + mv[9] * nrm[o + 2];
          var nz = mv[2] * nrm[o] + mv[6] * nrm[o + 1] + mv[10] * nrm[o + 2];
          var d = Math.abs(nx * L[0] + ny * L[1] + nz * L[2]) / (ll * (Math.hypot(nx, ny, nz) || 1));
          var g = 0.35 + 0.65 * d;
          var r = Math.round(255 * col[o] * g), gg = Math.round(255 * col[o + 1] * g), b = Math.round(255 * col[o + 2] * g);
          ctx.fillStyle = ctx.strokeStyle = "rgb(" + r + "," + gg + "," + b + ")";
          ctx.beginPath(); ctx.moveTo(sx[t * 3], syy[t * 3]); ctx.lineTo(sx[t * 3 + 1], syy[t * 3 + 1]);
          ctx.lineTo(sx[t * 3 + 2], syy[t * 3 + 2]); ctx.closePath(); ctx.fill(); ctx.stroke();
        }
      };
      root.dataset.mode = "canvas2d";
    }
    function resize() {
      var r = canvas.getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
      canvas.width = Math.max(1, Math.round(r.width * dpr)); canvas.height = Math.max(1, Math.round(r.height * dpr));
    }
    var pending = false;
    function redraw() {
      if (pending) return; pending = true;
      (window.requestAnimationFrame || setTimeout)(function () { pending = false; draw(); });
    }
    var drag = null;
    canvas.addEventListener("pointerdown", function (e) { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
    canvas.addEventListener("pointerup", function () { drag = null; });
    canvas.addEventListener("pointermove", function (e) {
      if (!drag) return;
      view.yaw += (e.clientX - drag[0]) * 0.01; view.pitch = Math.max(-1.55, Math.min(1.55, view.pitch + (e.clientY - drag[1]) * 0.01));
      drag = [e.clientX, e.clientY]; redraw();
    });
    canvas.addEventListener("wheel", function (e) {
      e.preventDefault(); view.dist = Math.max(1.2, Math.min(20, view.dist * Math.exp(e.deltaY * 0.001))); redraw();
    }, { passive: false });
    slider.addEventListener("input", function () { setActivation(slider.value / 1000); redraw(); });
    var timer = null;
    play.addEventListener("click", function () {
      if (timer) { clearInterval(timer); timer = null; play.textContent = "play"; return; }
      if (slider.value >= 1000) slider.value = 0;
      play.textContent = "pause";
      timer = setInterval(function () {
        slider.value = Math.min(1000, +slider.value + 10); setActivation(slider.value / 1000); redraw();
        if (+slider.value >= 1000) { clearInterval(timer); timer = null; play.textContent = "play"; }
      }, 30);
    });
    window.addEventListener("resize", function () { resize(); redraw(); });
    resize();
    setActivation(act[F - 1]);
    slider.value = Math.round(act[F - 1] * 1000);
    draw();
    root.dataset.rendered = root.dataset.mode;
    root.querySelector(".status").textContent = T + " triangles, " + root.dataset.mode;
  };
})();
"""


def _json_script(obj):
    return json.dumps(obj).replace("</", "<\\/")


def viewer_fragment(data, element_id="gdfe-view"):
    """The viewer as an HTML fragment (a ``<div>`` with its style and scripts), for a larger page.

    Parameters
    ----------
    data : ViewData
    element_id : str
        The ``id`` of the viewer's element (unique on the page).
    """
    if not isinstance(data, ViewData):
        raise GdfeError(f"data: expected gdfe.fabrication.ViewData, got {type(data).__name__}")
    e = html.escape
    payload = data.payload()
    legend = "".join(
        f'<span style="background: rgb({", ".join(str(round(255 * c)) for c in rgb)})"></span>{e(name)}'
        for name, rgb in zip(payload["names"], payload["colours"]))
    info = " · ".join(f"{e(k)}: {e(v)}" for k, v in payload["info"].items())
    eid = e(element_id)
    return "\n".join([
        f"<style>{_CSS}</style>",
        f'<div class="gdfe-viewer" id="{eid}">',
        f"<canvas aria-label=\"3-D view of {e(data.title)}\"></canvas>",
        '<div class="controls"><button type="button">play</button>'
        '<input type="range" min="0" max="1000" step="1" value="1000" aria-label="activation">'
        '<span class="activation"></span></div>',
        f'<div class="legend">material:{legend}</div>',
        f'<div class="info">{info} · <span class="status">loading</span> · drag to turn, wheel to zoom</div>',
        f'<script type="application/json" class="gdfe-data">{_json_script(payload)}</script>',
        "</div>",
        f"<script>{_JS}</script>",
        "<script>(function () { var root = document.getElementById(" + json.dumps(element_id) + ");"
        " try { gdfeViewer(root, JSON.parse(root.querySelector('.gdfe-data').textContent)); }"
        " catch (err) { root.dataset.error = String(err); root.querySelector('.status').textContent ="
        " 'error: ' + err; } })();</script>",
    ])


def viewer_page(data):
    """A complete, self-contained HTML page with the viewer of ``data``."""
    e = html.escape
    return "\n".join(["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
                      '<meta name="viewport" content="width=device-width, initial-scale=1">',
                      f"<title>{e(data.title)}</title>",
                      "<style>body { margin: 1.5em auto; max-width: 980px; }</style></head><body>",
                      f'<h1 style="font: bold 1.3em sans-serif">{e(data.title)}</h1>',
                      viewer_fragment(data), "</body></html>", ""])


def write_viewer(path, data):
    """Write :func:`viewer_page` of ``data`` (a :class:`ViewData` or a :class:`gdfe.Result`) to ``path``."""
    from gdfe.io import write_text

    if not isinstance(data, ViewData):
        data = view_data(data, title=Path(path).stem)
    return write_text(path, viewer_page(data))
