// The page's glue around the C decoder (web/mts_web.h, compiled to
// WebAssembly): WebSocket bytes, or a stream file's ranges fetched over
// HTTP(S) (?src=URL), in; WebGL2 draws out; the controls. The
// decoding, the levels, the strip packing, the camera and the strip colours
// are the C's; this file moves bytes and calls GL.
'use strict';

(function () {
  const params = new URLSearchParams(location.search);
  const $ = (id) => document.getElementById(id);
  const canvas = $('view');
  if (params.get('bare') === '1') document.body.classList.add('bare');
  // every animation frame drawn, not only those after a change: to measure
  // what the page can draw (make bench)
  const redraw = params.get('redraw') === '1';
  // a level change slides over this long (the window client's default)
  const morphMs = params.get('morph') !== null ? Number(params.get('morph')) : 250;
  // ?colors=0: grey even where the model has vertex colours (mts-client --no-colors)
  const noColors = params.get('colors') === '0';

  // What the page shows, published into #state (JSON) for tests.
  const state = {
    phase: 'loading', model: '', error: '', level: 0, received: 0, stop_level: 0, levels: 0,
    triangles: 0, strips: 0, vertices: 0, batches: 0, bytes: 0, checksum: '',
    server_checksum: '', ms_connect: 0, ms_base: 0, ms_first_frame: 0, ms_final: 0, decode_ms: 0,
    frames: 0, fps: 0, draw_ms_total: 0, draw_ms_max: 0, frames_streaming: 0,
    morphing: false, morph_ms: 0, models: [],
    requests: 0, reconnects: 0, first_batch: 0, colors: false,
    threads: 0, isolated: self.crossOriginIsolated === true,
  };
  window.mtsState = state;
  const publish = () => { $('state').textContent = JSON.stringify(state); };

  // The web server that hands out the page proxies the stream at /stream
  // (web/nginx.conf); over https that is wss://, as a secure page requires.
  // A stream file (mts-build --stream) from any web server that answers
  // Range requests: this page's, or another origin's that sends CORS
  // headers (docker/nginx-tls.conf's .mts location). No WebSocket then.
  const src = params.get('src');
  // a cut range is asked for again from the first batch not held, after
  // waits that double from 250 ms up to 4 s, this many times in a row
  const retries = params.get('retries') !== null ? Number(params.get('retries')) : 8;
  const serverUrl = params.get('server') ||
      ((location.protocol === 'https:' ? 'wss://' : 'ws://') + (location.host || '127.0.0.1:7448') +
       '/stream');

  let M = null;        // the WebAssembly module
  // The decoder's threads: ?threads=2 runs a pool thread beside the
  // page's (the threaded build, mts_web_mt.wasm) where the page is
  // cross-origin isolated, so that its shared memory exists; anything else,
  // or a page that is not isolated, runs the one-thread build. One is the
  // default: on the machine measured two were slower in Chromium
  // (docs/browser.md, "Threads").
  let threaded = params.get('threads') === '2' && self.crossOriginIsolated === true &&
      typeof SharedArrayBuffer === 'function';
  // The module's memory seen from here. The threaded build's pool thread
  // may grow the shared memory, and emscripten renews the views on M only
  // where the growing thread runs: a view this thread holds would end at
  // the old size. So every read goes through these, which renew them once
  // the memory's buffer is another (never with one thread: no wasmMemory).
  function heapViews() {
    const mem = M.wasmMemory;
    if (mem && M.HEAPU8.buffer !== mem.buffer) {
      M.HEAPU8 = new Uint8Array(mem.buffer);
      M.HEAPU32 = new Uint32Array(mem.buffer);
      M.HEAPF32 = new Float32Array(mem.buffer);
    }
    return M;
  }
  const heapU8 = () => heapViews().HEAPU8;
  const heapU32 = () => heapViews().HEAPU32;
  const heapF32 = () => heapViews().HEAPF32;
  let w = 0;           // its mts_web*
  let ws = null;
  let file = null;     // the stream file's conversation (?src=)
  let gl = null, prog = null, vbo = null, nbo = null, mbo = null, ibo = null;
  // with colours (as the native renderer's layout.colors): RGBA8 a vertex in
  // cbo, the morph's from-colours in mcbo, and programs built with COLORS 1;
  // a model without colours has none of them
  let cbo = null, mcbo = null, colorCapacity = 0;
  let morphSerial = -1; // the morph range whose from-places mbo holds
  let uploadedVertices = 0, vertexCapacity = 0, indexCount = 0, packedLevel = -1;
  const cam = {yaw: Number(params.get('yaw') || 30), pitch: Number(params.get('pitch') || 20),
               zoom: Number(params.get('zoom') || 1)};
  let dirty = true, t0 = 0;

  function fail(text) {
    state.error = text;
    state.phase = 'error';
    $('error').textContent = text;
    $('error').hidden = false;
    $('status').textContent = 'failed';
    publish();
    dirty = true;
  }

  // ---- GL: the native renderer's shaders, light and colours (camera.c) -----
  let style = null; // background rgba, surface rgb, ambient, light xyz

  function initGL() {
    gl = canvas.getContext('webgl2', {antialias: false, preserveDrawingBuffer: true});
    if (!gl) throw new Error('this browser has no WebGL2');
    const sh = (type, src) => {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      return s;
    };
    // as the native renderer: a plain program, and one that morphs a range;
    // those with COLORS 1 are built when a model with colours first draws
    const build = (morph, colors) => {
      const p = gl.createProgram();
      const head = `#version 300 es\n#define MORPH ${morph}\n#define COLORS ${colors}\n`;
      gl.attachShader(p, sh(gl.VERTEX_SHADER, head + M.UTF8ToString(M._mts_web_shader(0))));
      gl.attachShader(p, sh(gl.FRAGMENT_SHADER, head + M.UTF8ToString(M._mts_web_shader(1))));
      gl.linkProgram(p);
      if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
      p.u = {};
      for (const u of ['u_mvp', 'u_normal', 'u_color', 'u_light', 'u_ambient', 'u_flat',
                       'u_morph', 'u_morph_t', 'u_vertex_color'])
        p.u[u] = gl.getUniformLocation(p, u);
      return p;
    };
    prog = [build(0, 0), build(1, 0), null, null];
    prog.get = (morph, colors) => prog[2 * colors + morph] || (prog[2 * colors + morph] = build(morph, colors));
    vbo = gl.createBuffer();
    nbo = gl.createBuffer();
    mbo = gl.createBuffer();
    ibo = gl.createBuffer();
  }

  // New vertices appended (the stream only appends); the buffers grow by doubling.
  function uploadVertices() {
    const nv = M._mts_web_vertices(w);
    if (nv <= uploadedVertices) return;
    const pos = M._mts_web_positions(w) >> 2, nrm = M._mts_web_normals(w) >> 2;
    const from = nv > vertexCapacity ? 0 : uploadedVertices;
    if (nv > vertexCapacity) {
      vertexCapacity = Math.max(nv, 2 * vertexCapacity);
      for (const b of [vbo, nbo]) {
        gl.bindBuffer(gl.ARRAY_BUFFER, b);
        gl.bufferData(gl.ARRAY_BUFFER, vertexCapacity * 12, gl.DYNAMIC_DRAW);
      }
      // the morph's from-places: positions, then normals, by vertex id
      gl.bindBuffer(gl.ARRAY_BUFFER, mbo);
      gl.bufferData(gl.ARRAY_BUFFER, vertexCapacity * 24, gl.DYNAMIC_DRAW);
      morphSerial = -1;
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
    gl.bufferSubData(gl.ARRAY_BUFFER, from * 12, heapF32().subarray(pos + 3 * from, pos + 3 * nv));
    gl.bindBuffer(gl.ARRAY_BUFFER, nbo);
    gl.bufferSubData(gl.ARRAY_BUFFER, from * 12, heapF32().subarray(nrm + 3 * from, nrm + 3 * nv));
    uploadColors(from, nv);
    uploadedVertices = nv;
  }

  // The colours of vertices from .. nv-1, RGBA8, where the model has them;
  // the buffers are made (or grown, everything sent again) with the vertices'.
  function withColors() { return !noColors && w && M._mts_web_has_colors(w) !== 0; }
  function uploadColors(from, nv) {
    if (!withColors()) return;
    if (colorCapacity < vertexCapacity) {
      if (!cbo) { cbo = gl.createBuffer(); mcbo = gl.createBuffer(); }
      colorCapacity = vertexCapacity;
      for (const b of [cbo, mcbo]) {
        gl.bindBuffer(gl.ARRAY_BUFFER, b);
        gl.bufferData(gl.ARRAY_BUFFER, colorCapacity * 4, gl.DYNAMIC_DRAW);
      }
      from = 0;
      morphSerial = -1;
    }
    const c = M._mts_web_colors_rgba(w, from, nv - from);
    if (!c) return;
    gl.bindBuffer(gl.ARRAY_BUFFER, cbo);
    gl.bufferSubData(gl.ARRAY_BUFFER, from * 4, heapU8().subarray(c, c + 4 * (nv - from)));
    state.colors = true;
  }

  // The level to show: the slider's, or all that came while following.
  function wantedLevel() {
    return $('follow').checked ? M._mts_web_received_level(w) : Number($('level').value);
  }

  // A morph's range, where it changed: its from-places into mbo.
  function uploadMorph() {
    const serial = M._mts_web_morph_serial(w), count = M._mts_web_morph_count(w);
    if (serial === morphSerial || !count) return;
    const first = M._mts_web_morph_first(w), from = M._mts_web_morph_from(w) >> 2;
    gl.bindBuffer(gl.ARRAY_BUFFER, mbo);
    gl.bufferSubData(gl.ARRAY_BUFFER, first * 12, heapF32().subarray(from, from + 3 * count));
    gl.bufferSubData(gl.ARRAY_BUFFER, vertexCapacity * 12 + first * 12,
                     heapF32().subarray(from + 3 * count, from + 6 * count));
    const c = withColors() ? M._mts_web_morph_from_colors_rgba(w) : 0;
    if (c) {
      gl.bindBuffer(gl.ARRAY_BUFFER, mcbo);
      gl.bufferSubData(gl.ARRAY_BUFFER, first * 4, heapU8().subarray(c, c + 4 * count));
    }
    morphSerial = serial;
  }

  function pack() {
    if (M._mts_web_show(w, wantedLevel(), performance.now()) !== 0)
      return fail(M.UTF8ToString(M._mts_web_error(w)));
    state.morphing = M._mts_web_morph_active(w) !== 0;
    if (state.morphing) dirty = true; // the next frame goes on with it
    const level = M._mts_web_shown_level(w);
    if (level === packedLevel && indexCount) return;
    const p = M._mts_web_indices(w) >> 2;
    indexCount = M._mts_web_index_count(w);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, heapU32().subarray(p, p + indexCount), gl.DYNAMIC_DRAW);
    packedLevel = level;
    state.level = level;
    state.triangles = M._mts_web_shown_triangles(w);
    state.strips = M._mts_web_shown_strips(w);
  }

  let lastFrame = 0, frameTimes = [];
  function draw(now) {
    requestAnimationFrame(draw);
    pump(performance.now() + 12); // most of a 60 Hz frame, the rest to draw
    if ((!dirty && !redraw) || !w || M._mts_web_state(w) < 2) return;
    dirty = false;
    const d0 = performance.now();
    uploadVertices();
    pack();
    uploadMorph();
    const cw = canvas.clientWidth | 0, ch = canvas.clientHeight | 0;
    if (canvas.width !== cw || canvas.height !== ch) { canvas.width = cw; canvas.height = ch; }
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(style[0], style[1], style[2], style[3]);
    gl.clearDepth(1.0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.frontFace(gl.CCW);
    gl.cullFace(gl.BACK);
    gl.enable(gl.CULL_FACE);
    // at t = 1 every vertex is at its own place: the plain program draws that exactly
    const t = M._mts_web_morph_t(w);
    const morph = state.morphing && M._mts_web_morph_count(w) > 0 && t < 1 ? 1 : 0;
    const colors = state.colors ? 1 : 0;
    const pg = prog.get(morph, colors);
    gl.useProgram(pg);
    const m = M._mts_web_camera(w, cam.yaw, cam.pitch, cam.zoom, canvas.width / canvas.height) >> 2;
    gl.uniformMatrix4fv(pg.u.u_mvp, false, heapF32().subarray(m, m + 16));
    gl.uniformMatrix3fv(pg.u.u_normal, false, heapF32().subarray(m + 16, m + 25));
    gl.uniform3f(pg.u.u_light, style[8], style[9], style[10]);
    gl.uniform1f(pg.u.u_ambient, style[7]);
    gl.uniform1i(pg.u.u_flat, M._mts_web_flat(w));
    gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, nbo);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 0, 0);
    for (const a of [2, 3]) {
      if (morph) {
        gl.bindBuffer(gl.ARRAY_BUFFER, mbo);
        gl.enableVertexAttribArray(a);
        gl.vertexAttribPointer(a, 3, gl.FLOAT, false, 0, a === 2 ? 0 : vertexCapacity * 12);
      } else {
        gl.disableVertexAttribArray(a);
      }
    }
    for (const a of [4, 5]) { // the colours, and the morph's from-colours
      if (colors && (a === 4 || morph)) {
        gl.bindBuffer(gl.ARRAY_BUFFER, a === 4 ? cbo : mcbo);
        gl.enableVertexAttribArray(a);
        gl.vertexAttribPointer(a, 4, gl.UNSIGNED_BYTE, true, 0, 0);
      } else {
        gl.disableVertexAttribArray(a);
      }
    }
    if (colors) gl.uniform1i(pg.u.u_vertex_color, $('strips').checked ? 0 : 1);
    if (morph) {
      const first = M._mts_web_morph_first(w);
      gl.uniform2ui(pg.u.u_morph, first, first + M._mts_web_morph_count(w));
      gl.uniform1f(pg.u.u_morph_t, t);
    }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
    if ($('strips').checked) {
      const k = M._mts_web_strip_count(w);
      const first = M._mts_web_strip_first(w) >> 2, len = M._mts_web_strip_length(w) >> 2;
      const rgb = M._mts_web_strip_colors(w) >> 2;
      const f32 = heapF32(), u32 = heapU32();
      for (let s = 0; s < k; s++) {
        gl.uniform3f(pg.u.u_color, f32[rgb + 3 * s], f32[rgb + 3 * s + 1], f32[rgb + 3 * s + 2]);
        gl.drawElements(gl.TRIANGLE_STRIP, u32[len + s], gl.UNSIGNED_INT, 4 * u32[first + s]);
      }
    } else {
      gl.uniform3f(pg.u.u_color, style[4], style[5], style[6]);
      gl.drawElements(gl.TRIANGLE_STRIP, indexCount, gl.UNSIGNED_INT, 0);
    }
    // the script's share of a frame (uploads, packing, GL calls; not the
    // GPU's), for `make bench`
    const spent = performance.now() - d0;
    state.draw_ms_total += spent;
    state.draw_ms_max = Math.max(state.draw_ms_max, spent);
    state.frames++;
    if (!state.ms_first_frame) state.ms_first_frame = performance.now() - t0;
    frameTimes.push(now);
    while (frameTimes.length > 1 && now - frameTimes[0] > 1000) frameTimes.shift();
    state.fps = frameTimes.length > 1 ? Math.round(1000 * (frameTimes.length - 1) / (now - frameTimes[0])) : 0;
    lastFrame = now;
    hud();
  }

  function hud() {
    const lv = $('level');
    lv.max = String(state.received);
    // a stream file's next stop: the full level unless one is typed
    if (src && $('stop').value === '0' && state.levels) $('stop').value = String(state.levels);
    if ($('follow').checked) lv.value = String(state.received);
    $('hud').textContent =
      `level     ${state.level} / ${state.levels} (received ${state.received})\n` +
      `triangles ${state.triangles}   strips ${state.strips}\n` +
      `vertices  ${state.vertices}   batches ${state.batches}\n` +
      `bytes     ${state.bytes}\n` +
      `first frame ${state.ms_first_frame.toFixed(1)} ms   final ${state.ms_final ? state.ms_final.toFixed(1) + ' ms' : '-'}\n` +
      `decode    ${state.decode_ms.toFixed(1)} ms   ${state.fps} fps\n` +
      (morphMs > 0 ? `morph     ${morphMs} ms${state.morphing ? ' (morphing)' : ''}` : 'morph     off');
    $('status').textContent = state.phase;
    publish();
  }

  // ---- the conversation ----------------------------------------------------
  // paced: the messages wait in a queue that draw() decodes a slice of each
  // animation frame (pump), so the page draws while a fast stream is still
  // coming; decoded as they come, a burst of batches holds the first picture
  // back until the browser forces a frame (~100 ms of bunny00 here). The
  // close is taken once the queue is empty: nothing received is dropped.
  // The bytes of one conversation on their way to the decoder: feed copies
  // them into the module's memory and hands them to onBytes; end frees that.
  function inboxOf(onBytes, onClose) {
    const c = {buf: 0, cap: 0, queue: [], closed: null, onBytes, onClose};
    c.feed = (data) => {
      if (data.length > c.cap) {
        if (c.buf) M._free(c.buf);
        c.cap = Math.max(data.length, 65536);
        c.buf = M._malloc(c.cap);
      }
      heapU8().set(data, c.buf);
      c.onBytes(c.buf, data.length);
    };
    c.end = (ev) => { if (c.buf) M._free(c.buf); c.buf = 0; c.onClose(ev); };
    return c;
  }

  // The paced stream's queue goes with it when another starts.
  function dropInbox() {
    if (!inbox) return;
    inbox.queue.length = 0;
    inbox.closed = null;
    if (inbox.buf) M._free(inbox.buf);
    inbox.buf = inbox.cap = 0;
    inbox = null;
  }

  function connect(onOpen, onBytes, onClose, paced) {
    const sock = new WebSocket(serverUrl);
    sock.binaryType = 'arraybuffer';
    const c = inboxOf(onBytes, onClose);
    sock.onopen = () => onOpen(sock);
    sock.onmessage = (ev) => {
      if (paced) c.queue.push(new Uint8Array(ev.data));
      else c.feed(new Uint8Array(ev.data));
    };
    sock.onclose = (ev) => {
      if (paced && c.queue.length) c.closed = ev;
      else c.end(ev);
    };
    sock.onerror = () => {};
    if (paced) inbox = c;
    return sock;
  }

  let inbox = null;  // the paced stream's connection
  let lastPump = 0;
  // Decodes queued messages until `until` (performance.now() ms), and all
  // of them while the base mesh is not in yet: nothing to draw before it.
  function pump(until) {
    const c = inbox;
    lastPump = performance.now();
    if (!c) return;
    while (c.queue.length && (performance.now() < until || !w || M._mts_web_state(w) < 2))
      c.feed(c.queue.shift());
    if (!c.queue.length && c.closed) {
      const ev = c.closed;
      c.closed = null;
      c.end(ev);
    }
  }

  function list(then) {
    const lw = M._mts_web_create();
    connect((sock) => {
      const p = M._mts_web_list(lw);
      sock.send(heapU8().slice(p, p + M._mts_web_out_size(lw)));
    }, (p, n) => { M._mts_web_feed(lw, p, n); }, () => {
      const text = M.UTF8ToString(M._mts_web_models(lw));
      M._mts_web_destroy(lw);
      state.models = text.split('\n').filter((l) => l).map((l) => {
        const [name, vertices, triangles, levels] = l.split(' ');
        return {name, vertices: +vertices, triangles: +triangles, levels: +levels};
      });
      const sel = $('model');
      sel.innerHTML = '';
      for (const m of state.models) {
        const o = document.createElement('option');
        o.value = m.name;
        o.textContent = `${m.name} (${m.triangles} triangles)`;
        sel.appendChild(o);
      }
      then();
    });
  }

  // A new decoder and a clean slate for a stream of `name`.
  function restart(name) {
    if (ws) { ws.onclose = null; ws.close(); }
    if (file) file.abort.abort();
    file = null;
    if (w) M._mts_web_destroy(w);
    w = M._mts_web_create();
    M._mts_web_set_threads(w, threaded ? 2 : 1);
    M._mts_web_set_morph_ms(w, morphMs);
    morphSerial = -1;
    Object.assign(state, {phase: 'connecting', model: name, error: '', level: 0, received: 0,
                          stop_level: 0, levels: 0, triangles: 0, strips: 0, vertices: 0,
                          batches: 0, bytes: 0, checksum: '', server_checksum: '', ms_connect: 0, ms_base: 0,
                          ms_first_frame: 0, ms_final: 0, decode_ms: 0, frames: 0,
                          draw_ms_total: 0, draw_ms_max: 0, frames_streaming: 0,
                          morphing: false, morph_ms: morphMs, requests: 0, reconnects: 0,
                          first_batch: 0, colors: false, threads: 0});
    $('error').hidden = true;
    uploadedVertices = vertexCapacity = indexCount = colorCapacity = 0;
    packedLevel = -1;
  }

  // What the decoder says after bytes were taken (or the stream ended).
  function progress() {
    state.received = M._mts_web_received_level(w);
    state.stop_level = M._mts_web_stop_level(w);
    state.levels = M._mts_web_level_count(w);
    state.vertices = M._mts_web_vertices(w);
    state.batches = M._mts_web_batches(w);
    if (!state.ms_base && M._mts_web_state(w) >= 2) {
      state.ms_base = performance.now() - t0;
      state.threads = M._mts_web_threads(w); // those the decoder runs, known at the base
    }
    if (M._mts_web_state(w) === 3) {
      state.phase = 'complete';
      state.ms_final = performance.now() - t0;
      state.frames_streaming = state.frames; // drawn while it came
      state.checksum = M.UTF8ToString(M._mts_web_checksum(w));
      state.server_checksum = M.UTF8ToString(M._mts_web_server_checksum(w));
    }
    dirty = true;
    publish();
  }

  function stream(name) {
    restart(name);
    const stopLevel = params.get('level');
    t0 = performance.now();
    const mine = w;
    const nameBuf = M._malloc(80);
    M.stringToUTF8(name, nameBuf, 80);
    const hello = M._mts_web_hello(w, nameBuf, stopLevel !== null ? 1 : 0, Number(stopLevel || 0),
                                   0);
    M._free(nameBuf);
    const helloBytes = heapU8().slice(hello, hello + M._mts_web_out_size(w));
    dropInbox();
    ws = connect((sock) => {
      state.ms_connect = performance.now() - t0;
      state.phase = 'streaming';
      sock.send(helloBytes);
      publish();
    }, (p, n) => {
      if (w !== mine || state.phase === 'error') return;
      const d0 = performance.now();
      const rc = M._mts_web_feed(w, p, n);
      state.decode_ms += performance.now() - d0;
      state.bytes += n;
      if (rc !== 0) return fail(M.UTF8ToString(M._mts_web_error(w)));
      progress();
    }, (ev) => {
      if (w !== mine) return;
      if (state.phase !== 'complete' && state.phase !== 'error')
        fail(`the connection closed at level ${state.received} of ${state.stop_level || '?'}` +
             (ev.reason ? ` (${ev.reason})` : '') + '; the picture stops there');
    }, true);
  }

  // ---- a stream file over HTTP(S) (?src=URL; web/mts_web.h) ----------------
  // The native client's conversation (client/webfile.c): the file's first
  // 4 KB (its prefix and, for most models, the start of BASE), the rest of
  // the prefix when it is longer, then one ranged GET from BASE -- or, for a
  // resume or a continuation, from the first batch not held -- to the end
  // of the stop's last batch, decoded as it arrives. The C plans, decodes
  // and verifies; this moves the bytes.
  const FIRST_REQUEST = 4096; // MTS_SFILE_FIRST_REQUEST

  // An HTTP failure; `again` when a new request may cure it (a cut, a
  // server down or a 5xx), as the native client's MTS_ERR_IO.
  function httpError(text, again) {
    const e = new Error(text);
    e.again = again;
    return e;
  }

  function decoderError() {
    return httpError(`${src}: ${M.UTF8ToString(M._mts_web_error(w))}`, false);
  }

  // The stream is over: no byte more is fetched for it.
  function fileFail(f, text) {
    f.abort.abort();
    fail(text);
  }

  // bytes into the module's memory for one call
  function withBytes(data, fn) {
    const p = M._malloc(Math.max(data.length, 1));
    heapU8().set(data, p);
    try { return fn(p, data.length); } finally { M._free(p); }
  }

  // One GET of bytes [from, to) of the file (upTo: the file may end
  // sooner), the body handed to onChunk piece by piece as it arrives, cut
  // to the range: from a server that ignored Range (200, the whole file)
  // the bytes before `from` are skipped and the transfer stopped at `to`.
  // A 206 must say it holds exactly the bytes asked for.
  async function getRange(f, from, to, upTo, onChunk) {
    let res;
    state.requests++;
    try {
      // every range after the first is of the same file: If-Range with the
      // first answer's strong ETag makes a server whose file was rebuilt
      // answer 200, which the check below refuses
      const headers = {Range: `bytes=${from}-${to - 1}`};
      if (f.etag) headers['If-Range'] = f.etag;
      res = await fetch(src, {headers, signal: f.abort.signal});
    } catch (e) {
      throw httpError(`${src}: ${e.message || e}`, true);
    }
    if (!state.ms_connect) state.ms_connect = performance.now() - t0;
    if (res.status === 200 || res.status === 206) {
      const tag = res.headers.get('ETag');
      const strong = tag && tag.startsWith('"') ? tag : null;
      if (f.etag === undefined) {
        f.etag = strong; // null: the server shows none (or only a weak one)
      } else if (f.etag && strong !== f.etag) {
        throw httpError(`${src}: the file changed on the server since its first bytes were ` +
                        `read (ETag ${f.etag}, now ${tag || 'none'}): start again`, false);
      }
    }
    let skip = 0;
    if (res.status === 206) {
      const cr = res.headers.get('Content-Range');
      if (!cr)
        throw httpError(`${src}: a 206 without Content-Range (a server of another origin ` +
                        'must expose it: Access-Control-Expose-Headers)', false);
      const m = /^\s*bytes\s+(\d+)-(\d+)\/(\d+|\*)\s*$/i.exec(cr);
      const size = M._mts_web_file_size(w);
      if (!m || Number(m[1]) !== from || Number(m[2]) < from ||
          (upTo ? Number(m[2]) > to - 1 : Number(m[2]) !== to - 1) ||
          (size && m[3] !== '*' && Number(m[3]) !== size))
        throw httpError(`${src}: the wrong range: asked for bytes ${from}-${to - 1}, ` +
                        `got Content-Range: ${cr}`, false);
    } else if (res.status === 200) {
      skip = from;
    } else {
      throw httpError(`${src}: HTTP ${res.status}${res.statusText ? ' ' + res.statusText : ''}`,
                      res.status >= 500 || res.status === 408 || res.status === 429);
    }
    if (!res.body) throw httpError(`${src}: the response has no body`, false);
    const reader = res.body.getReader();
    const want = to - from;
    let got = 0;
    try {
      while (got < want) {
        const {done, value} = await reader.read();
        if (done) break;
        state.bytes += value.length;
        let chunk = value;
        if (skip) {
          const n = Math.min(skip, chunk.length);
          chunk = chunk.subarray(n);
          skip -= n;
        }
        if (chunk.length > want - got) chunk = chunk.subarray(0, want - got);
        if (chunk.length) {
          got += chunk.length;
          onChunk(chunk);
        }
      }
    } catch (e) {
      if (f.abort.signal.aborted) throw e;
      throw httpError(`${src}: the transfer broke after ${got} of ${want} bytes ` +
                      `(${e.message || e})`, true);
    }
    if (got >= want) reader.cancel().catch(() => {}); // the rest of a 200's file
    if (got < want && !upTo)
      throw httpError(`${src}: the range ended early, after ${got} of ${want} bytes`, true);
    return got;
  }

  // The prefix, read once and kept (f.pre: the file's first bytes, the
  // start of BASE among them), and the index parsed from it.
  async function filePrefix(f) {
    const parts = [];
    let have = 0;
    const take = (chunk) => { parts.push(chunk); have += chunk.length; };
    const joined = () => {
      const all = new Uint8Array(have);
      let at = 0;
      for (const p of parts) { all.set(p, at); at += p.length; }
      return all;
    };
    await getRange(f, 0, FIRST_REQUEST, true, take);
    let pre = joined();
    const need = withBytes(pre, (p, n) => M._mts_web_file_prefix_size(w, p, n));
    if (need < 0) throw decoderError();
    if (need > have) {
      await getRange(f, have, need, false, take);
      pre = joined();
    }
    if (withBytes(pre, (p, n) => M._mts_web_file_index(w, p, n)) !== 0) throw decoderError();
    f.pre = pre;
  }

  // Plans f's stop from the first batch not held and fetches its range;
  // the bytes are decoded from the paced queue, as the WebSocket's.
  function fileRange(f) {
    const mine = w;
    state.first_batch = M._mts_web_file_resume_point(w); // the range starts there
    if (M._mts_web_file_plan(w, f.kind, f.value) !== 0 || M._mts_web_file_begin(w) !== 0)
      return fileFail(f, decoderError().message);
    progress();
    const from = M._mts_web_file_from(w), to = M._mts_web_file_to(w);
    const c = inboxOf((p, n) => {
      if (w !== mine || file !== f || state.phase === 'error') return;
      const d0 = performance.now();
      const rc = M._mts_web_file_feed(w, p, n);
      state.decode_ms += performance.now() - d0;
      if (rc !== 0) return fileFail(f, decoderError().message);
      f.tries = 0; // bytes came: a later cut starts counting again
      progress();
    }, (ev) => {
      if (w !== mine || file !== f || state.phase === 'error') return;
      if (ev.error) return fileRetry(f, ev.error);
      if (!M._mts_web_file_done(w))
        return fileRetry(f, httpError(`${src}: the range ended early`, true));
      if (M._mts_web_file_end(w) !== 0) return fileFail(f, decoderError().message);
      progress();
    });
    dropInbox();
    inbox = c;
    let next = from;
    if (f.pre && f.pre.length > from) { // what came with the prefix
      next = Math.min(f.pre.length, to);
      c.queue.push(f.pre.subarray(from, next));
    }
    if (next >= to) {
      c.closed = {};
      return;
    }
    getRange(f, next, to, false, (chunk) => c.queue.push(chunk))
        .then(() => { c.closed = {}; }, (e) => { c.closed = {error: e}; });
  }

  // One step of the conversation: the prefix when it is not in yet, then
  // the range.
  async function fileStep(f) {
    try {
      if (!f.pre) await filePrefix(f);
    } catch (e) {
      return fileRetry(f, e);
    }
    if (file !== f) return;
    state.phase = 'streaming';
    fileRange(f);
  }

  // After a failure: once everything that came is decoded, a new request
  // from the first batch not held, when one may help.
  function fileRetry(f, e) {
    if (file !== f || f.abort.signal.aborted || state.phase === 'error') return;
    if (!e.again || M._mts_web_file_resume_point(w) < 0 || f.tries >= retries)
      return fileFail(f, e.again ? `${e.message}; gave up after ${f.tries} tries, at level ` +
                            `${state.received} of ${state.stop_level || '?'}` : e.message);
    f.tries++;
    state.reconnects++;
    state.phase = 'reconnecting';
    publish();
    setTimeout(() => { if (file === f) fileStep(f); }, Math.min(4000, 250 * 2 ** (f.tries - 1)));
  }

  function fileStream() {
    restart(src.replace(/[?#].*$/, '').split('/').pop() || src);
    const stopLevel = params.get('level');
    t0 = performance.now();
    dropInbox();
    file = {abort: new AbortController(), pre: null, kind: stopLevel !== null ? 1 : 0,
            value: Number(stopLevel || 0), tries: 0};
    publish();
    fileStep(file);
  }

  // On to a higher stop once the last is in: one range, from the first
  // batch not held. false when there is nothing to continue.
  function fileContinue(level) {
    const f = file;
    if (!f || state.phase !== 'complete' || !(level > state.stop_level) ||
        state.stop_level >= state.levels)
      return false;
    f.kind = level >= state.levels ? 0 : 1;
    f.value = level >= state.levels ? 0 : level;
    f.tries = 0;
    state.phase = 'streaming';
    state.checksum = state.server_checksum = '';
    state.ms_final = 0;
    t0 = performance.now();
    fileRange(f);
    return true;
  }
  window.mtsContinue = fileContinue;

  // ---- controls --------------------------------------------------------------
  function controls() {
    let drag = null;
    canvas.addEventListener('pointerdown', (e) => { drag = {x: e.clientX, y: e.clientY}; canvas.setPointerCapture(e.pointerId); });
    canvas.addEventListener('pointerup', () => { drag = null; });
    canvas.addEventListener('pointermove', (e) => {
      if (!drag) return;
      cam.yaw -= (e.clientX - drag.x) * 0.4;
      cam.pitch = Math.max(-89, Math.min(89, cam.pitch + (e.clientY - drag.y) * 0.4));
      drag = {x: e.clientX, y: e.clientY};
      dirty = true;
    });
    canvas.addEventListener('wheel', (e) => {
      e.preventDefault();
      cam.zoom = Math.max(0.1, Math.min(50, cam.zoom * Math.exp(-e.deltaY * 0.001)));
      dirty = true;
    }, {passive: false});
    $('level').addEventListener('input', () => { $('follow').checked = false; dirty = true; });
    $('follow').addEventListener('change', () => { dirty = true; });
    $('strips').addEventListener('change', () => { dirty = true; });
    if (src) {
      const o = document.createElement('option');
      o.textContent = src;
      $('model').appendChild(o);
      $('model').disabled = true;
      $('more-row').hidden = false;
      $('more').addEventListener('click', () => fileContinue(Number($('stop').value)));
      $('reload').addEventListener('click', () => fileStream());
    } else {
      $('model').addEventListener('change', () => stream($('model').value));
      $('reload').addEventListener('click', () => stream($('model').value));
    }
    if (params.get('strips') === '1') $('strips').checked = true;
    if (params.get('level') !== null) $('follow').checked = true;
    window.addEventListener('resize', () => { dirty = true; });
  }

  async function main() {
    try {
      const draco = await DracoDecoderModule();
      // The decoder runs here, on the page's thread, in slices of each
      // animation frame (pump); the threaded build's pool thread is a Web
      // Worker. This thread may not block (Atomics.wait is refused on a
      // page's main thread), so where the decoder waits for the pool
      // thread (at a batch's end, for the records not made yet)
      // emscripten spins. A decoder in a worker of its own could sleep
      // there, but every frame's draw would then read the mesh from
      // another thread's decoder under a lock, and Draco's decoder (this
      // thread's) would be called across: a redesign that the measured
      // two threads do not justify (docs/browser.md, "Threads").
      const load = (name) => new Promise((resolve, reject) => {
        const s = document.createElement('script');
        s.src = name;
        s.onload = resolve;
        s.onerror = () => reject(new Error(`cannot load ${s.src}`));
        document.head.appendChild(s);
      });
      // a server without the threaded build's files: one thread
      if (threaded) threaded = await load('mts_web_mt.js').then(() => true, () => false);
      if (!threaded) await load('mts_web.js');
      M = await (threaded ? createMtsWebMt : createMtsWeb)();
      M.draco = draco;
      const sw = M._mts_web_create(), sp = M._mts_web_style(sw) >> 2;
      style = Array.from(heapF32().subarray(sp, sp + 11));
      M._mts_web_destroy(sw);
      initGL();
    } catch (e) {
      return fail('cannot start: ' + (e && e.message || e));
    }
    controls();
    requestAnimationFrame(draw);
    // a hidden page gets no animation frames: the stream is decoded anyway
    setInterval(() => { if (performance.now() - lastPump > 200) pump(performance.now() + 50); }, 100);
    if (src) return fileStream();
    list(() => {
      const want = params.get('model') || (state.models[0] && state.models[0].name);
      if (!want) return fail(`no models listed by ${serverUrl}`);
      $('model').value = want;
      stream(want);
    });
  }
  main();
})();
