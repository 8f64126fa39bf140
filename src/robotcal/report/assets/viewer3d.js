/* robotcal 3-D viewer: measured circle points, fitted circles and joint axes on a 2-D canvas.
 *
 * Hand-written for the self-contained report: no library, no WebGL. Every element with class
 * "rc-viewer" holds a <canvas>, a <script type="application/json"> with the scene (lengths in mm)
 * and an empty legend <div>. Orthographic projection; drag rotates, wheel zooms, shift-drag pans,
 * double-click resets, arrow keys and +/- do the same from the keyboard.
 * After its first drawing the canvas gets data-rendered="1" and data-ink=<number of drawn pixels>,
 * which the report's self-check and the browser test read.
 */
(function () {
  "use strict";

  var DEFAULT_VIEW = { yaw: -0.6, pitch: 0.35, zoom: 1.0, panX: 0, panY: 0 };

  function niceStep(range, count) {
    var raw = range / Math.max(count, 1);
    var power = Math.pow(10, Math.floor(Math.log10(raw)));
    var steps = [1, 2, 2.5, 5, 10];
    for (var i = 0; i < steps.length; i++) {
      if (steps[i] * power >= raw) return steps[i] * power;
    }
    return 10 * power;
  }

  function formatTick(value, step) {
    var decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
    return value.toFixed(Math.min(decimals, 6));
  }

  function Viewer(root) {
    this.root = root;
    this.canvas = root.querySelector("canvas");
    this.context = this.canvas.getContext("2d");
    this.scene = JSON.parse(root.querySelector("script[type='application/json']").textContent);
    this.legend = root.querySelector(".rc-legend");
    this.readout = root.querySelector(".rc-readout");
    this.view = Object.assign({}, DEFAULT_VIEW);
    this.show = { points: true, circles: true, axes: true, frames: true };
    this.hidden = {};
    var lo = this.scene.bounds.min, hi = this.scene.bounds.max;
    this.centre = [0, 1, 2].map(function (k) { return 0.5 * (lo[k] + hi[k]); });
    this.extent = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-9);
    this.diagonal = Math.max(Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]), 1e-9);
    this.buildLegend();
    this.bindEvents();
    this.resize();
  }

  Viewer.prototype.buildLegend = function () {
    var self = this;
    function toggle(label, colour, onChange) {
      var item = document.createElement("label");
      item.className = "rc-legend-item";
      var box = document.createElement("input");
      box.type = "checkbox";
      box.checked = true;
      box.addEventListener("change", function () { onChange(box.checked); self.draw(); });
      item.appendChild(box);
      if (colour) {
        var swatch = document.createElement("span");
        swatch.className = "rc-swatch";
        swatch.style.background = colour;
        item.appendChild(swatch);
      }
      item.appendChild(document.createTextNode(label));
      self.legend.appendChild(item);
    }
    this.scene.circles.forEach(function (circle, index) {
      toggle(circle.label + " (" + circle.points.length + " points, r = " + circle.radius.toFixed(3) + " mm)",
        circle.colour, function (on) { self.hidden[index] = !on; });
    });
    toggle("points", null, function (on) { self.show.points = on; });
    toggle("fitted circles", null, function (on) { self.show.circles = on; });
    toggle("joint axes", null, function (on) { self.show.axes = on; });
    if (this.scene.frames && this.scene.frames.length) {
      toggle("frames", null, function (on) { self.show.frames = on; });
    }
  };

  Viewer.prototype.bindEvents = function () {
    var self = this, canvas = this.canvas, drag = null;
    canvas.addEventListener("pointerdown", function (event) {
      drag = { x: event.clientX, y: event.clientY, pan: event.shiftKey || event.button === 2 };
      if (canvas.setPointerCapture) canvas.setPointerCapture(event.pointerId);
    });
    canvas.addEventListener("pointermove", function (event) {
      if (!drag) return;
      var dx = event.clientX - drag.x, dy = event.clientY - drag.y;
      drag.x = event.clientX;
      drag.y = event.clientY;
      if (drag.pan) {
        self.view.panX += dx;
        self.view.panY += dy;
      } else {
        self.rotate(dx * 0.01, dy * 0.01);
      }
      self.draw();
    });
    function end() { drag = null; }
    canvas.addEventListener("pointerup", end);
    canvas.addEventListener("pointercancel", end);
    canvas.addEventListener("contextmenu", function (event) { event.preventDefault(); });
    canvas.addEventListener("wheel", function (event) {
      event.preventDefault();
      self.zoomBy(Math.exp(-event.deltaY * 0.0015));
    }, { passive: false });
    canvas.addEventListener("dblclick", function () { self.reset(); });
    canvas.addEventListener("keydown", function (event) {
      var handled = true;
      switch (event.key) {
        case "ArrowLeft": self.rotate(-0.1, 0); break;
        case "ArrowRight": self.rotate(0.1, 0); break;
        case "ArrowUp": self.rotate(0, -0.1); break;
        case "ArrowDown": self.rotate(0, 0.1); break;
        case "+": case "=": self.zoomBy(1.2); break;
        case "-": self.zoomBy(1 / 1.2); break;
        case "0": self.reset(); break;
        default: handled = false;
      }
      if (handled) { event.preventDefault(); self.draw(); }
    });
    var button = this.root.querySelector(".rc-reset");
    if (button) button.addEventListener("click", function () { self.reset(); });
    if (window.ResizeObserver) {
      new ResizeObserver(function () { self.resize(); }).observe(this.root);
    } else {
      window.addEventListener("resize", function () { self.resize(); });
    }
  };

  Viewer.prototype.rotate = function (dYaw, dPitch) {
    this.view.yaw += dYaw;
    this.view.pitch = Math.max(-Math.PI / 2, Math.min(Math.PI / 2, this.view.pitch + dPitch));
  };

  Viewer.prototype.zoomBy = function (factor) {
    this.view.zoom = Math.max(0.2, Math.min(50, this.view.zoom * factor));
    this.draw();
  };

  Viewer.prototype.reset = function () {
    this.view = Object.assign({}, DEFAULT_VIEW);
    this.draw();
  };

  Viewer.prototype.resize = function () {
    var parent = this.canvas.parentNode, style = window.getComputedStyle(parent);
    var inner = parent.clientWidth - parseFloat(style.paddingLeft || "0") - parseFloat(style.paddingRight || "0");
    var width = Math.max(320, Math.floor(inner || 800));
    var height = Math.round(Math.min(620, Math.max(320, width * 0.62)));
    var ratio = window.devicePixelRatio || 1;
    if (this.width === width && this.height === height && this.ratio === ratio) return;
    this.width = width;
    this.height = height;
    this.ratio = ratio;
    this.canvas.width = Math.round(width * ratio);
    this.canvas.height = Math.round(height * ratio);
    this.canvas.style.width = width + "px";
    this.canvas.style.height = height + "px";
    this.draw();
  };

  /* World point [mm] -> [screen x, screen y, depth]; camera looks along +depth, world z is up. */
  Viewer.prototype.project = function (p) {
    var v = this.view, c = this.centre;
    var x = p[0] - c[0], y = p[1] - c[1], z = p[2] - c[2];
    var cy = Math.cos(v.yaw), sy = Math.sin(v.yaw), cp = Math.cos(v.pitch), sp = Math.sin(v.pitch);
    var x1 = cy * x - sy * y, y1 = sy * x + cy * y;
    var y2 = cp * y1 - sp * z, z2 = sp * y1 + cp * z;
    var scale = v.zoom * 0.86 * Math.min(this.width, this.height) / this.diagonal;
    return [this.width / 2 + v.panX + x1 * scale, this.height / 2 + v.panY - z2 * scale, y2];
  };

  Viewer.prototype.line = function (a, b, colour, width, dash) {
    var g = this.context, pa = this.project(a), pb = this.project(b);
    g.beginPath();
    g.setLineDash(dash || []);
    g.strokeStyle = colour;
    g.lineWidth = width;
    g.moveTo(pa[0], pa[1]);
    g.lineTo(pb[0], pb[1]);
    g.stroke();
    g.setLineDash([]);
  };

  /* Labels are queued while the scene is drawn and placed last (flushLabels), most important first, each
   * where it overlaps no label placed before it: tick labels that would overlap are left out, titles and
   * axis labels are moved up or down a line until they fit. */
  var FONT = "11px system-ui, -apple-system, 'Segoe UI', sans-serif";
  var BOLD = "bold 12px system-ui, -apple-system, 'Segoe UI', sans-serif";

  Viewer.prototype.text = function (p, label, colour, align, font, priority) {
    var s = this.project(p);
    this.labels.push({ x: s[0], y: s[1], label: label, colour: colour, align: align || "center",
      font: font || FONT, priority: priority || 1, order: this.labels.length });
  };

  Viewer.prototype.flushLabels = function () {
    var g = this.context, placed = [], overlaps = 0;
    g.textBaseline = "middle";
    this.labels.sort(function (a, b) { return b.priority - a.priority || a.order - b.order; });
    function box(item, dy, width) {
      var left = item.align === "left" ? item.x : item.align === "right" ? item.x - width : item.x - width / 2;
      return [left - 2, item.y + dy - 8, left + width + 2, item.y + dy + 8];
    }
    function free(r) {
      for (var i = 0; i < placed.length; i++) {
        var q = placed[i];
        if (r[0] < q[2] && q[0] < r[2] && r[1] < q[3] && q[1] < r[3]) return false;
      }
      return true;
    }
    var shifts = [0, 14, -14, 28, -28, 42, -42, 56, -56, 70, -70];
    for (var k = 0; k < this.labels.length; k++) {
      var item = this.labels[k];
      g.font = item.font;
      var width = g.measureText(item.label).width, chosen = null;
      var tries = item.priority > 1 ? shifts : [0];
      for (var t = 0; t < tries.length && chosen === null; t++) {
        if (free(box(item, tries[t], width))) chosen = tries[t];
      }
      if (chosen === null) {
        if (item.priority === 1) continue;  // a tick label that would overlap: left out
        chosen = 0;
        overlaps++;
      }
      placed.push(box(item, chosen, width));
      g.textAlign = item.align;
      g.lineWidth = 3;
      g.strokeStyle = "rgba(255, 255, 255, 0.85)";  // a halo keeps the label legible over points and lines
      g.strokeText(item.label, item.x, item.y + chosen);
      g.fillStyle = item.colour;
      g.fillText(item.label, item.x, item.y + chosen);
    }
    this.canvas.dataset.labels = String(placed.length);
    this.canvas.dataset.labelOverlaps = String(overlaps);
  };

  Viewer.prototype.drawBox = function () {
    var lo = this.scene.bounds.min, hi = this.scene.bounds.max, self = this;
    var corners = [];
    for (var i = 0; i < 8; i++) {
      corners.push([i & 1 ? hi[0] : lo[0], i & 2 ? hi[1] : lo[1], i & 4 ? hi[2] : lo[2]]);
    }
    [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]]
      .forEach(function (e) { self.line(corners[e[0]], corners[e[1]], "#c8ccd2", 1); });
    var names = ["X", "Y", "Z"];
    // ticks of X along (y = lo, z = lo), Y along (x = hi, z = lo), Z along (x = lo, y = lo)
    var anchors = [[null, lo[1], lo[2]], [hi[0], null, lo[2]], [lo[0], lo[1], null]];
    var offsets = [[0, -1, 0], [1, 0, 0], [-1, -1, 0]];
    for (var k = 0; k < 3; k++) {
      var range = hi[k] - lo[k];
      if (!(range > 0)) continue;
      var step = niceStep(range, 4), pad = 0.04 * this.extent;
      for (var t = Math.ceil(lo[k] / step) * step; t <= hi[k] + 1e-9 * range; t += step) {
        var at = anchors[k].slice();
        at[k] = t;
        var tickEnd = at.map(function (value, j) { return value + offsets[k][j] * pad * 0.5; });
        this.line(at, tickEnd, "#8a9099", 1);
        var labelAt = at.map(function (value, j) { return value + offsets[k][j] * pad * 1.6; });
        this.text(labelAt, formatTick(t, step), "#4a5058");
      }
      var middle = anchors[k].slice();
      middle[k] = 0.5 * (lo[k] + hi[k]);
      var titleAt = middle.map(function (value, j) { return value + offsets[k][j] * pad * 4.2; });
      this.text(titleAt, names[k] + " (mm)", "#1d2733", "center", BOLD, 3);
    }
  };

  Viewer.prototype.drawFrames = function () {
    var self = this, colours = ["#d62728", "#2ca02c", "#1f77b4"];
    (this.scene.frames || []).forEach(function (frame) {
      ["x", "y", "z"].forEach(function (axis, k) {
        var end = frame.origin.map(function (value, j) { return value + frame.length * frame[axis][j]; });
        self.line(frame.origin, end, colours[k], 2);
        self.text(end, axis, colours[k], "center", BOLD, 2);
      });
      self.text(frame.origin, frame.label, "#1d2733", "right", BOLD, 2);
    });
  };

  Viewer.prototype.drawCircle = function (circle) {
    var g = this.context, n = 144;
    g.beginPath();
    g.strokeStyle = circle.colour;
    g.lineWidth = 1.6;
    for (var i = 0; i <= n; i++) {
      var t = 2 * Math.PI * i / n, c = Math.cos(t) * circle.radius, s = Math.sin(t) * circle.radius;
      var p = [0, 1, 2].map(function (k) { return circle.centre[k] + c * circle.u[k] + s * circle.v[k]; });
      var q = this.project(p);
      if (i === 0) g.moveTo(q[0], q[1]); else g.lineTo(q[0], q[1]);
    }
    g.stroke();
  };

  Viewer.prototype.drawAxis = function (axis, colour) {
    var a = [], b = [];
    for (var k = 0; k < 3; k++) {
      a.push(axis.point[k] - axis.half_length * axis.direction[k]);
      b.push(axis.point[k] + axis.half_length * axis.direction[k]);
    }
    this.line(a, b, colour, 1.8, [7, 4]);
    this.text(b, axis.label, colour, "left", BOLD, 2);
  };

  Viewer.prototype.draw = function () {
    if (!this.width) return;
    var g = this.context, self = this;
    g.setTransform(this.ratio, 0, 0, this.ratio, 0, 0);
    g.fillStyle = "#ffffff";
    g.fillRect(0, 0, this.width, this.height);
    this.labels = [];
    this.drawBox();
    if (this.show.frames) this.drawFrames();
    var circles = this.scene.circles;
    circles.forEach(function (circle, index) {
      if (self.hidden[index]) return;
      if (self.show.circles) self.drawCircle(circle);
    });
    (this.scene.axes || []).forEach(function (axis) {
      var index = axis.circle;
      if (self.hidden[index] || !self.show.axes) return;
      self.drawAxis(axis, circles[index] ? circles[index].colour : "#333333");
    });
    if (this.show.points) {
      var marks = [];
      circles.forEach(function (circle, index) {
        if (self.hidden[index]) return;
        circle.points.forEach(function (p) { marks.push([self.project(p), circle.colour]); });
      });
      marks.sort(function (a, b) { return b[0][2] - a[0][2]; });  // far first
      marks.forEach(function (mark) {
        g.beginPath();
        g.arc(mark[0][0], mark[0][1], 3.2, 0, 2 * Math.PI);
        g.fillStyle = mark[1];
        g.fill();
        g.lineWidth = 0.8;
        g.strokeStyle = "#ffffff";
        g.stroke();
      });
    }
    this.flushLabels();
    if (this.readout) {
      this.readout.textContent = "azimuth " + (this.view.yaw * 180 / Math.PI).toFixed(0) + "°, elevation " +
        (this.view.pitch * 180 / Math.PI).toFixed(0) + "°, zoom " + this.view.zoom.toFixed(2) + "×";
    }
    if (this.canvas.dataset.rendered !== "1") this.markRendered();
  };

  /* Count the non-white pixels once, so that a blank canvas can be told from a drawn one. */
  Viewer.prototype.markRendered = function () {
    var pixels = this.context.getImageData(0, 0, this.canvas.width, this.canvas.height).data, ink = 0;
    for (var i = 0; i < pixels.length; i += 4) {
      if (pixels[i] < 250 || pixels[i + 1] < 250 || pixels[i + 2] < 250) ink++;
    }
    this.canvas.dataset.ink = String(ink);
    this.canvas.dataset.rendered = "1";
  };

  window.robotcalViewers = [];
  var roots = document.querySelectorAll(".rc-viewer");
  for (var i = 0; i < roots.length; i++) window.robotcalViewers.push(new Viewer(roots[i]));
})();
