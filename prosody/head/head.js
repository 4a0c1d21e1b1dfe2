"use strict";
// The 3D head of prosody.head drawn with WebGL from FAP frames: the mesh, fields, camera and lights of the CPU
// renderer (prosody/head/render.py), read from the model JSON the server sends (prosody/head/web.py).
// A frame's FAP values deform the mesh here (rest + sum of value x field, in cm per FAP unit); the head turns
// in the vertex shader about the top of the spine, R = Rz(roll) Ry(yaw) Rx(pitch) from FAP 48-50 (1e-5 rad);
// the fragment shader lights it as the CPU renderer does (two lights, ambient, a weak highlight, both sides).
(function () {
  const AU = 1e-5;
  const VERTEX = `
    attribute vec3 position; attribute vec3 normal; attribute vec3 color; attribute float rotates;
    uniform mat3 turn; uniform vec3 pivot; uniform vec4 camera; uniform vec2 halfSize;
    varying vec3 vNormal; varying vec3 vColor;
    void main() {
      vec3 p = position, n = normal;
      if (rotates > 0.0) {  // the share of the head's turn this vertex follows (the neck bends)
        p = mix(position, turn * (position - pivot) + pivot, rotates); n = normalize(mix(normal, turn * normal, rotates));
      }
      float depth = camera.x - p.z;  // camera.x: distance, .y: look-at height, .z: focal (px), .w: far
      float x = camera.z * p.x / halfSize.x, y = camera.z * (p.y - camera.y) / halfSize.y;
      float z = (depth / camera.w) * 2.0 - 1.0;
      gl_Position = vec4(x, y, z * depth, depth);
      vNormal = n; vColor = color;
    }`;
  const FRAGMENT = `
    precision mediump float;
    uniform vec3 light0; uniform vec3 light1; uniform vec4 strengths; uniform float shininess;
    varying vec3 vNormal; varying vec3 vColor;
    void main() {
      vec3 n = normalize(vNormal);
      if (n.z < 0.0) n = -n;  // lit from both sides, as the CPU renderer
      float diffuse = strengths.z, specular = 0.0;
      vec3 lights[2]; lights[0] = light0; lights[1] = light1;
      float power[2]; power[0] = strengths.x; power[1] = strengths.y;
      for (int k = 0; k < 2; k++) {
        float lambert = dot(n, lights[k]);
        if (lambert > 0.0) {
          diffuse += power[k] * lambert;
          float c = dot(n, normalize(lights[k] + vec3(0.0, 0.0, 1.0)));
          if (c > 0.0) specular += power[k] * pow(c, shininess);
        }
      }
      gl_FragColor = vec4(min(vColor * diffuse + strengths.w * specular, vec3(1.0)), 1.0);
    }`;

  function rotation(p, y, r) {  // R = Rz(r) Ry(y) Rx(p), column-major for WebGL
    const [cx, sx, cy, sy, cz, sz] = [Math.cos(p), Math.sin(p), Math.cos(y), Math.sin(y), Math.cos(r), Math.sin(r)];
    const m = [[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
               [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
               [-sy, cy * sx, cy * cx]];
    return new Float32Array([m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1], m[0][2], m[1][2], m[2][2]]);
  }

  // A linked program of two shader sources; a compile or link error is thrown with WebGL's log.
  function compile(gl, vertex, fragment) {
    const program = gl.createProgram();
    for (const [kind, source] of [[gl.VERTEX_SHADER, vertex], [gl.FRAGMENT_SHADER, fragment]]) {
      const shader = gl.createShader(kind);
      gl.shaderSource(shader, source); gl.compileShader(shader);
      if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
      gl.attachShader(program, shader);
    }
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
    return program;
  }

  class HeadView {
    constructor(canvas, model, shaders) {
      // no multisampling: where WebGL runs in software (SwiftShader) it costs four times the pixels
      const gl = shaders ? shaders.gl : canvas.getContext("webgl", { antialias: false, preserveDrawingBuffer: true });
      if (!gl) throw new Error("WebGL is not available in this browser");
      this.gl = gl; this.canvas = canvas; this.model = model;
      this.rest = new Float32Array(model.vertices);
      this.positions = new Float32Array(this.rest.length);
      this.normals = new Float32Array(this.rest.length);
      this.triangles = new Uint16Array(model.triangles);
      this.fields = {};
      for (const [fap, field] of Object.entries(model.fields)) {
        this.fields[fap] = { vertices: Int32Array.from(field.vertices), offsets: Float32Array.from(field.offsets) };
      }
      const program = shaders ? compile(gl, shaders.vertex, shaders.fragment) : compile(gl, VERTEX, FRAGMENT);
      this.program = program;
      gl.useProgram(program);
      const buffer = (name, data, size, usage) => this.attribute(name, data, size, usage);
      this.positionBuffer = buffer("position", this.positions, 3, gl.DYNAMIC_DRAW);
      this.normalBuffer = buffer("normal", this.normals, 3, gl.DYNAMIC_DRAW);
      buffer("color", new Float32Array(model.colors), 3, gl.STATIC_DRAW);
      buffer("rotates", new Float32Array(model.rotates), 1, gl.STATIC_DRAW);
      const index = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, index);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, this.triangles, gl.STATIC_DRAW);
      const u = (name) => gl.getUniformLocation(program, name);
      this.uniforms = { turn: u("turn"), pivot: u("pivot"), camera: u("camera"), halfSize: u("halfSize") };
      const lights = model.lights;
      gl.uniform3fv(u("light0"), lights.directions[0]); gl.uniform3fv(u("light1"), lights.directions[1]);
      gl.uniform4f(u("strengths"), lights.key, lights.fill, lights.ambient, lights.specular);
      gl.uniform1f(u("shininess"), lights.shininess);
      gl.uniform3fv(this.uniforms.pivot, model.pivot);
      gl.enable(gl.DEPTH_TEST);
    }

    // A vertex attribute from an array (its buffer); an attribute the shaders do not use is left out.
    attribute(name, data, size, usage) {
      const gl = this.gl;
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, usage || gl.STATIC_DRAW);
      const at = gl.getAttribLocation(this.program, name);
      if (at >= 0) {
        gl.enableVertexAttribArray(at); gl.vertexAttribPointer(at, size, gl.FLOAT, false, 0, 0);
        (this.bound = this.bound || []).push([at, b, size]);
      }
      return b;
    }

    // The camera's uniforms and the colour behind the head.
    project() {
      const gl = this.gl, w = this.canvas.width, h = this.canvas.height, cam = this.model.camera;
      const focal = (h / 2) / (cam.half_view_cm / cam.distance_cm);
      gl.uniform4f(this.uniforms.camera, cam.distance_cm, cam.look_at_y_cm, focal, 2 * cam.distance_cm);
      gl.uniform2f(this.uniforms.halfSize, w / 2, h / 2);
      const bg = this.model.background;
      gl.clearColor(bg[0], bg[1], bg[2], 1);
    }

    // Draw one frame: faps maps FAP numbers to values (FAP units); absent is neutral.
    draw(faps) {
      const started = performance.now();
      const gl = this.gl, pos = this.positions, nrm = this.normals;
      pos.set(this.rest);
      for (const [fap, value] of Object.entries(faps || {})) {
        const field = this.fields[fap];
        if (!field || !value) continue;
        const { vertices, offsets } = field;
        for (let i = 0; i < vertices.length; i++) {
          const v = 3 * vertices[i], o = 3 * i;
          pos[v] += value * offsets[o]; pos[v + 1] += value * offsets[o + 1]; pos[v + 2] += value * offsets[o + 2];
        }
      }
      nrm.fill(0);
      const t = this.triangles;
      for (let i = 0; i < t.length; i += 3) {
        const a = 3 * t[i], b = 3 * t[i + 1], c = 3 * t[i + 2];
        const ux = pos[b] - pos[a], uy = pos[b + 1] - pos[a + 1], uz = pos[b + 2] - pos[a + 2];
        const vx = pos[c] - pos[a], vy = pos[c + 1] - pos[a + 1], vz = pos[c + 2] - pos[a + 2];
        const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
        for (const k of [a, b, c]) { nrm[k] += nx; nrm[k + 1] += ny; nrm[k + 2] += nz; }
      }
      gl.bindBuffer(gl.ARRAY_BUFFER, this.positionBuffer); gl.bufferSubData(gl.ARRAY_BUFFER, 0, pos);
      gl.bindBuffer(gl.ARRAY_BUFFER, this.normalBuffer); gl.bufferSubData(gl.ARRAY_BUFFER, 0, nrm);
      const angle = (n) => ((faps && faps[n]) || 0) * AU;
      gl.uniformMatrix3fv(this.uniforms.turn, false, rotation(angle(48), angle(49), angle(50)));
      this.project();
      gl.viewport(0, 0, this.canvas.width, this.canvas.height);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.drawElements(gl.TRIANGLES, t.length, gl.UNSIGNED_SHORT, 0);
      this.drawMs = performance.now() - started;
    }
  }

  // A person's head from a photo (prosody/head/photo.py, model "kind": "photo"): vertices in the photo's pixels
  // (x right, y up, z towards the camera); the face and the person's grid show the photo as it was taken (the
  // face shaded anew as it turns, the light staying put), the mouth's inside is lit; the head turns about the
  // pivot by each vertex's share, and the motion is laid over the photo's framing as a camera photo.camera_px
  // away sees it (PhotoRenderer does the same on the CPU).
  const INSIDE_ALPHA = "(254.0 / 255.0)";  // the drawn inside's mark in the off-screen frame (see softenFragment)
  const PHOTO_VERTEX = `
    attribute vec3 position; attribute vec3 rest; attribute vec3 normal; attribute vec3 color;
    attribute float rotates; attribute vec2 uv; attribute float textured; attribute float behind;
    attribute vec3 restNormal; attribute float relit;
    uniform mat3 turn; uniform vec3 pivot; uniform vec4 photo;  // width, height, camera distance, depth range
    uniform vec3 relightDirection; uniform vec3 relightLimits;  // ambient share, lowest and highest gain
    varying vec3 vNormal; varying vec3 vColor; varying vec2 vUV; varying float vTextured; varying float vGain;
    vec2 seen(vec3 p) {
      vec2 centre = vec2(0.5 * photo.x, -0.5 * photo.y);
      return centre + (p.xy - centre) * (photo.z / max(photo.z - p.z, 0.001 * photo.z));
    }
    float light(vec3 n) { return relightLimits.x + (1.0 - relightLimits.x) * max(dot(n, relightDirection), 0.0); }
    void main() {
      vec3 p = position, n = normal;
      vGain = 1.0;
      if (rotates > 0.0) {
        p = mix(position, turn * (position - pivot) + pivot, rotates); n = normalize(mix(normal, turn * normal, rotates));
        if (relit > 0.0) {  // the light stays where it was in the photo: a turned surface takes its light now
          vec3 turned = normalize(mix(restNormal, turn * restNormal, rotates));  // over its light then
          float gain = clamp(light(turned) / max(light(restNormal), relightLimits.x), relightLimits.y, relightLimits.z);
          vGain = 1.0 + relit * (gain - 1.0);
        }
      }
      vec2 xy = rest.xy + seen(p) - seen(rest);
      float z = clamp((behind - (p.z - pivot.z)) / photo.w, -1.0, 1.0);
      gl_Position = vec4(2.0 * xy.x / photo.x - 1.0, 1.0 + 2.0 * xy.y / photo.y, z, 1.0);
      vNormal = n; vColor = color; vUV = uv; vTextured = textured;
    }`;
  const PHOTO_FRAGMENT = `
    precision mediump float;
    uniform sampler2D image;
    uniform vec3 light0; uniform vec3 light1; uniform vec4 strengths; uniform float shininess;
    varying vec3 vNormal; varying vec3 vColor; varying vec2 vUV; varying float vGain;
    varying float vTextured;
    // a light gain as PhotoRenderer's rasteriser applies it (prosody/head/raster.py, lit): above 1 each value
    // moves towards white by a share of the room it has left, so nothing clips
    vec3 lit(vec3 value, float gain) {
      if (gain <= 1.0) return value * gain;
      vec3 room = max(1.0 - value, vec3(1e-4));
      return min(value + room * (1.0 - exp(-(gain - 1.0) * value / room)), vec3(1.0));
    }
    void main() {
      // the photo's alpha is the person's coverage: round the outline the background behind the canvas shows
      if (vTextured > 0.5) {
        vec4 t = texture2D(image, vUV);
        gl_FragColor = vec4(lit(t.rgb, vGain) * t.a, t.a);
        return;
      }
      vec3 n = normalize(vNormal);
      if (n.z < 0.0) n = -n;
      float diffuse = strengths.z + strengths.x * max(dot(n, light0), 0.0) + strengths.y * max(dot(n, light1), 0.0);
      gl_FragColor = vec4(min(vColor * diffuse, vec3(1.0)), ${INSIDE_ALPHA});  // marks the drawn inside
    }`;
  // The drawn mouth's inside made as soft as the photographed face round it, as PhotoRenderer does on the CPU:
  // the frame is drawn off screen with the inside marked by an alpha of 254/255 (the face there is opaque); it is
  // copied to the canvas and, within the box round the inside (a scissor: no other pixel pays for it), blurred
  // by a Gaussian of the given sigma (canvas pixels), weighted by twice the blurred mark, at most 1.
  const SOFTEN_VERTEX = `
    attribute vec2 corner;
    void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;
  // reach: the blur's reach in canvas pixels (3 sigma, whole), fixed in the source so that no pixel loops further
  const softenFragment = (reach) => `
    precision mediump float;
    uniform sampler2D frame; uniform vec2 size; uniform float sigma;  // sigma 0: a plain copy
    const int REACH = ${reach};
    float inside(vec4 c) { return abs(c.a - ${INSIDE_ALPHA}) < 0.5 / 255.0 ? 1.0 : 0.0; }
    void main() {
      vec2 px = gl_FragCoord.xy;
      vec4 here = texture2D(frame, px / size);
      float mark = inside(here);
      if (sigma <= 0.0) {
        gl_FragColor = vec4(here.rgb, mix(here.a, 1.0, mark));
        return;
      }
      vec3 sum = vec3(0.0); float marks = 0.0, total = 0.0;
      for (int dy = -REACH; dy <= REACH; dy++) {
        for (int dx = -REACH; dx <= REACH; dx++) {
          vec2 d = vec2(float(dx), float(dy));
          float w = exp(-dot(d, d) / (2.0 * sigma * sigma));
          vec4 c = texture2D(frame, (px + d) / size);
          sum += w * c.rgb; marks += w * inside(c); total += w;
        }
      }
      float weight = clamp(2.0 * marks / total, 0.0, 1.0);
      gl_FragColor = vec4(here.rgb + weight * (sum / total - here.rgb), mix(here.a, 1.0, mark));
    }`;

  class PhotoView extends HeadView {
    constructor(canvas, model, image) {
      canvas.height = Math.round(canvas.width * model.photo.height / model.photo.width);
      canvas.style.background = `url(${model.photo.background}) center / 100% 100% no-repeat`;
      const gl = canvas.getContext("webgl", { antialias: false, preserveDrawingBuffer: true });
      if (!gl) throw new Error("WebGL is not available in this browser");
      // the base class's set-up, with the photo's shaders and attributes
      super(canvas, model, { gl, vertex: PHOTO_VERTEX, fragment: PHOTO_FRAGMENT });
      const program = this.program;
      this.attribute("rest", this.rest, 3);
      this.attribute("uv", new Float32Array(model.uv), 2);
      this.attribute("textured", new Float32Array(model.textured), 1);
      this.attribute("behind", new Float32Array(model.behind), 1);
      const relight = model.relight;
      this.attribute("restNormal", new Float32Array(relight.normals), 3);
      this.attribute("relit", new Float32Array(relight.shares), 1);
      gl.uniform3fv(gl.getUniformLocation(program, "relightDirection"), relight.direction);
      gl.uniform3f(gl.getUniformLocation(program, "relightLimits"), relight.ambient, relight.range[0], relight.range[1]);
      const texture = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, image);
      for (const [name, value] of [[gl.TEXTURE_MIN_FILTER, gl.LINEAR], [gl.TEXTURE_MAG_FILTER, gl.LINEAR],
                                   [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) {
        gl.texParameteri(gl.TEXTURE_2D, name, value);
      }
      gl.uniform1i(gl.getUniformLocation(program, "image"), 0);
      this.uniforms.photo = gl.getUniformLocation(program, "photo");
      this.image = texture;
      const inside = new Set(), t = this.triangles, textured = model.textured;  // the drawn triangles' vertices
      for (let i = 0; i < t.length; i += 3) {
        const corners = [t[i], t[i + 1], t[i + 2]];
        if (!corners.some((v) => textured[v])) corners.forEach((v) => inside.add(v));
      }
      this.insideVertices = [...inside];
    }

    // The softening program for a Gaussian of sigma (canvas pixels), and its full-canvas triangle.
    softenProgram(gl, sigma) {
      if (this.soften) gl.deleteProgram(this.soften.program);
      else this.corners = gl.createBuffer();
      const reach = Math.max(1, Math.min(8, Math.ceil(3 * sigma)));
      const program = compile(gl, SOFTEN_VERTEX, softenFragment(reach));
      gl.bindBuffer(gl.ARRAY_BUFFER, this.corners);
      gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);  // covers the canvas
      const u = (name) => gl.getUniformLocation(program, name);
      const corner = gl.getAttribLocation(program, "corner");
      this.soften = { program, reach, sigma: Math.min(sigma, reach / 3), corner,
        uniforms: { frame: u("frame"), size: u("size"), sigma: u("sigma") } };
    }

    // The off-screen frame (a texture and a depth buffer) at the canvas's size, made anew when that changes.
    target() {
      const gl = this.gl, w = this.canvas.width, h = this.canvas.height;
      if (this.offscreen && this.offscreen.w === w && this.offscreen.h === h) return this.offscreen;
      if (this.offscreen) {
        gl.deleteFramebuffer(this.offscreen.buffer); gl.deleteTexture(this.offscreen.texture);
        gl.deleteRenderbuffer(this.offscreen.depth);
      }
      const texture = gl.createTexture(), depth = gl.createRenderbuffer(), buffer = gl.createFramebuffer();
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, w, h, 0, gl.RGBA, gl.UNSIGNED_BYTE, null);
      for (const [name, value] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST],
                                   [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) {
        gl.texParameteri(gl.TEXTURE_2D, name, value);
      }
      gl.activeTexture(gl.TEXTURE0);
      gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT16, w, h);
      gl.bindFramebuffer(gl.FRAMEBUFFER, buffer);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, texture, 0);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      this.offscreen = { w, h, texture, depth, buffer };
      this.softenProgram(gl, this.model.photo.inside_softness_px * w / this.model.photo.width);
      return this.offscreen;
    }

    // The box (canvas pixels from the bottom left: left, bottom, right, top) round the drawn inside, where it
    // is this frame: the vertex shader's motion, turn and perspective for its few hundred vertices.
    insideBox(faps, margin) {
      const p = this.model.photo, pos = this.positions, rest = this.rest, pivot = this.model.pivot;
      const angle = (n) => ((faps && faps[n]) || 0) * AU;
      const m = rotation(angle(48), angle(49), angle(50)), rotates = this.model.rotates;
      const seen = (x, y, z) => {
        const k = p.camera_px / Math.max(p.camera_px - z, 0.001 * p.camera_px);
        return [0.5 * p.width + (x - 0.5 * p.width) * k, -0.5 * p.height + (y + 0.5 * p.height) * k];
      };
      const zoom = this.canvas.width / p.width;
      let [left, bottom, right, top] = [Infinity, Infinity, -Infinity, -Infinity];
      for (const i of this.insideVertices) {
        const v = [pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]], share = rotates[i];
        const d = [v[0] - pivot[0], v[1] - pivot[1], v[2] - pivot[2]];
        const t = [0, 1, 2].map((r) => m[r] * d[0] + m[3 + r] * d[1] + m[6 + r] * d[2] + pivot[r]);
        const q = v.map((value, r) => value + share * (t[r] - value));
        const [sx, sy] = seen(q[0], q[1], q[2]), [rx, ry] = seen(rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]);
        const x = (rest[3 * i] + sx - rx) * zoom, y = (p.height + rest[3 * i + 1] + sy - ry) * zoom;
        left = Math.min(left, x); right = Math.max(right, x); bottom = Math.min(bottom, y); top = Math.max(top, y);
      }
      return [left - margin, bottom - margin, right + margin, top + margin];
    }

    draw(faps) {
      const gl = this.gl, offscreen = this.target();
      gl.useProgram(this.program);
      for (const [at, buffer, size] of this.bound) {  // the softening pass used the attributes' slots
        gl.bindBuffer(gl.ARRAY_BUFFER, buffer); gl.vertexAttribPointer(at, size, gl.FLOAT, false, 0, 0);
      }
      gl.bindTexture(gl.TEXTURE_2D, this.image);
      gl.bindFramebuffer(gl.FRAMEBUFFER, offscreen.buffer);
      super.draw(faps);
      const started = performance.now();
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      const s = this.soften;
      gl.useProgram(s.program);
      gl.bindBuffer(gl.ARRAY_BUFFER, this.corners);
      gl.enableVertexAttribArray(s.corner); gl.vertexAttribPointer(s.corner, 2, gl.FLOAT, false, 0, 0);
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, offscreen.texture);
      gl.uniform1i(s.uniforms.frame, 1);
      gl.uniform2f(s.uniforms.size, offscreen.w, offscreen.h);
      gl.disable(gl.DEPTH_TEST);
      gl.clear(gl.COLOR_BUFFER_BIT);
      gl.uniform1f(s.uniforms.sigma, 0);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      const [left, bottom, right, top] = this.insideBox(faps, s.reach + 2).map(Math.round);
      if (right > left && top > bottom) {
        gl.enable(gl.SCISSOR_TEST);
        gl.scissor(left, bottom, right - left, top - bottom);
        gl.uniform1f(s.uniforms.sigma, s.sigma);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
        gl.disable(gl.SCISSOR_TEST);
      }
      gl.enable(gl.DEPTH_TEST);
      gl.activeTexture(gl.TEXTURE0);
      this.drawMs += performance.now() - started;
    }

    project() {  // the photo's framing (see PHOTO_VERTEX); the background shows where nothing is drawn
      const gl = this.gl, p = this.model.photo;
      gl.uniform4f(this.uniforms.photo, p.width, p.height, p.camera_px, p.depth_px);
      gl.clearColor(0, 0, 0, 0);
    }
  }

  // A view of a loaded model on the canvas: the 3D head, or a photo's head once its photo is loaded.
  async function view(canvas, model) {
    if (model.kind !== "photo") return new HeadView(canvas, model);
    const image = new Image();
    image.src = model.photo.texture;
    await image.decode();
    return new PhotoView(canvas, model, image);
  }

  // Load the model and make a view on the canvas; rejects when WebGL or the model is unavailable.
  async function load(canvas, url) {
    const response = await fetch(url || "/head.json");
    if (!response.ok) throw new Error(`the head model could not be loaded (${response.status})`);
    return view(canvas, await response.json());
  }
  window.ProsodyHead = { HeadView, PhotoView, load, view };
})();
