// Decodes a stream with the WebAssembly decoder, in node, and prints one
// JSON line: the checksums, the level, the figures of the packed draw, and
// the decode time (the bytes are all in memory first, so it is the
// decoder's alone).
//   node tests/web/decode.js WEB_DIR SOURCE [PIECE_BYTES [REPEAT]]
// REPEAT > 1 decodes the bytes that many times (a fresh decoder each) and
// reports the median time and the first (which includes WebAssembly's
// compile tiers).
// SOURCE: a file holding what a TCP client receives, or
// tcp:HOST:PORT:MODEL[:KIND:VALUE[:FLAGS]] to fetch it from an mts-server
// (KIND as HELLO's stop kind: 0 full, 1 level, 2 triangles, 3 millionths).
'use strict';
const fs = require('fs');
const path = require('path');

// What an mts-server sends for one HELLO (built by the decoder's own
// mts_web_hello), until it closes.
function fetchStream(M, w, spec) {
  const [, host, port, model, kind, value, flags] = spec.split(':');
  const name = M._malloc(80);
  M.stringToUTF8(model, name, 80);
  const p = M._mts_web_hello(w, name, Number(kind || 0), Number(value || 0), Number(flags || 0));
  M._free(name);
  const hello = Buffer.from(M.HEAPU8.slice(p, p + M._mts_web_out_size(w)));
  return new Promise((resolve, reject) => {
    const parts = [];
    const sock = require('net').connect(Number(port), host, () => sock.write(hello));
    sock.on('data', (d) => parts.push(d));
    sock.on('end', () => resolve(Buffer.concat(parts)));
    sock.on('error', reject);
  });
}

async function main() {
  const [webDir, streamFile, pieceArg, repeatArg] = process.argv.slice(2);
  if (!webDir || !streamFile) {
    console.error('usage: node tests/web/decode.js WEB_DIR STREAM_FILE [PIECE_BYTES]');
    process.exit(2);
  }
  const dir = path.resolve(webDir);
  const draco = await require(path.join(dir, 'draco_decoder_nodejs.js'))();
  const createMtsWeb = require(path.join(dir, 'mts_web.js'));
  const M = await createMtsWeb({wasmBinary: fs.readFileSync(path.join(dir, 'mts_web.wasm'))});
  M.draco = draco;
  const piece = Number(pieceArg || 32768);
  const repeat = Math.max(1, Number(repeatArg || 1));
  const fetcher = M._mts_web_create();
  const bytes = streamFile.startsWith('tcp:') ? await fetchStream(M, fetcher, streamFile)
                                               : fs.readFileSync(streamFile);
  M._mts_web_destroy(fetcher);
  const buf = M._malloc(piece);
  const times = [];
  let out = null;
  for (let r = 0; r < repeat; r++) {
    const w = M._mts_web_create();
    let rc = 0;
    const t0 = process.hrtime.bigint();
    for (let at = 0; at < bytes.length && rc === 0; at += piece) {
      const chunk = bytes.subarray(at, Math.min(at + piece, bytes.length));
      M.HEAPU8.set(chunk, buf);
      rc = M._mts_web_feed(w, buf, chunk.length);
    }
    times.push(Number(process.hrtime.bigint() - t0) / 1e6);
    if (r + 1 === repeat) {
      M._mts_web_show(w, M._mts_web_received_level(w), 0);
      const s = (f) => M.UTF8ToString(M['_mts_web_' + f](w));
      out = {
        rc: rc,
        error: s('error'),
        state: M._mts_web_state(w),
        bytes: bytes.length,
        level: M._mts_web_received_level(w),
        stop_level: M._mts_web_stop_level(w),
        vertices: M._mts_web_vertices(w),
        batches: M._mts_web_batches(w),
        checksum: s('checksum'),
        server_checksum: s('server_checksum'),
        shown_level: M._mts_web_shown_level(w),
        triangles: M._mts_web_shown_triangles(w),
        strips: M._mts_web_shown_strips(w),
        packed_indices: M._mts_web_index_count(w),
      };
    }
    M._mts_web_destroy(w);
  }
  M._free(buf);
  const sorted = times.slice().sort((a, b) => a - b);
  out.decode_ms_first = times[0];
  out.decode_ms = sorted[Math.floor(sorted.length / 2)];
  out.runs = repeat;
  console.log(JSON.stringify(out));
}

main().catch((e) => { console.error('decode.js: ' + (e && e.stack || e)); process.exit(1); });
