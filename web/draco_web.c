/* draco.h's decoder in the browser build: Draco's own WebAssembly decoder
 * (npm draco3d, loaded by the page as Module.draco before the first BASE)
 * reads the buffer; what it gives is checked and dequantized here, as
 * protocol/draco.cpp does over the native library: the integer positions
 * (the position transform skipped) on the buffer's grid through
 * mts_draco_dequantize, Draco's own normals, the colours (one COLOR
 * attribute of 3 unsigned bytes, as draco.cpp reads them), the faces as
 * Draco orders them.
 * The head is checked first (mts_draco_check_head) so that no declared
 * count reaches Draco unbounded.
 *
 * Encoding and renumbering are the server's: a browser never calls them,
 * and they say so. */
#include <emscripten/emscripten.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "draco.h"

/* Decodes into Module.mtsDraco (kept until take): counts[0..3] = points,
 * faces, whether normals came, whether colours came; grid[0..3] = origin,
 * range; *bits. 0 with a message in msg on failure. */
EM_JS(int, mts_web_draco_begin,
      (const uint8_t *data, size_t size, uint32_t *counts, float *grid, int *bits, char *msg,
       int msg_size),
      {
          const D = Module.draco;
          const fail = function(text, keep)
          {
              stringToUTF8("draco decode: " + text, msg, msg_size);
              if (keep) {
                  if (keep.qt) D.destroy(keep.qt);
                  D.destroy(keep.mesh);
                  D.destroy(keep.dec);
              }
              return 0;
          };
          if (!D)
              return fail("the Draco decoder (draco3d) is not loaded", null);
          const dec = new D.Decoder();
          const mesh = new D.Mesh();
          const k = {dec : dec, mesh : mesh, qt : null};
          dec.SkipAttributeTransform(D.POSITION);
          const st = dec.DecodeArrayToMesh(HEAP8.subarray(data, data + size), size, mesh);
          if (!st.ok())
              return fail(st.error_msg(), k);
          const pid = dec.GetAttributeId(mesh, D.POSITION);
          if (pid < 0)
              return fail("no position attribute", k);
          const pa = dec.GetAttribute(mesh, pid);
          if (pa.num_components() != 3 ||
              (pa.data_type() != D.DT_INT32 && pa.data_type() != D.DT_UINT32))
              return fail("positions are not 3 quantized integers", k);
          k.qt = new D.AttributeQuantizationTransform();
          if (!k.qt.InitFromAttribute(pa))
              return fail("positions carry no quantization grid", k);
          let na = null;
          const nid = dec.GetAttributeId(mesh, D.NORMAL);
          if (nid >= 0) {
              na = dec.GetAttribute(mesh, nid);
              if (na.num_components() != 3 || na.data_type() != D.DT_FLOAT32)
                  return fail("normals are not 3 floats", k);
          }
          let ca = null, colors = 0;
          for (let i = 0; i < mesh.num_attributes(); i++) {
              const a = dec.GetAttribute(mesh, i);
              if (a.attribute_type() === D.COLOR) {
                  ca = a;
                  colors++;
              }
          }
          if (colors > 1)
              return fail(colors + " colour attributes", k);
          if (ca && (ca.num_components() != 3 || ca.data_type() != D.DT_UINT8))
              return fail("colours are not 3 bytes", k);
          HEAPU32[counts >> 2] = mesh.num_points();
          HEAPU32[(counts >> 2) + 1] = mesh.num_faces();
          HEAPU32[(counts >> 2) + 2] = na ? 1 : 0;
          HEAPU32[(counts >> 2) + 3] = ca ? 1 : 0;
          for (let c = 0; c < 3; c++)
              HEAPF32[(grid >> 2) + c] = k.qt.min_value(c);
          HEAPF32[(grid >> 2) + 3] = k.qt.range();
          HEAP32[bits >> 2] = k.qt.quantization_bits();
          k.pa = pa;
          k.na = na;
          k.ca = ca;
          Module.mtsDraco = k;
          return 1;
      });

/* Copies what begin decoded into our arrays (normals and colors may be 0;
 * all 0: nothing is copied) and lets Draco's objects go. */
EM_JS(void, mts_web_draco_take,
      (uint32_t *quantized, float *normals, uint32_t *triangles, uint8_t *colors), {
    const D = Module.draco;
    const k = Module.mtsDraco;
    Module.mtsDraco = null;
    const copy = function(n, fill, dst, size)
    {
        const bytes = n * (size || 4);
        const p = D._malloc(bytes);
        fill(p);
        HEAPU8.set(D.HEAPU8.subarray(p, p + bytes), dst);
        D._free(p);
    };
    const np = k.mesh.num_points(), nf = k.mesh.num_faces();
    if (quantized) {
    copy(3 * np, function(p) {
        k.dec.GetAttributeDataArrayForAllPoints(k.mesh, k.pa, D.DT_UINT32, 12 * np, p);
    }, quantized);
    if (normals && k.na)
        copy(3 * np, function(p) {
            k.dec.GetAttributeDataArrayForAllPoints(k.mesh, k.na, D.DT_FLOAT32, 12 * np, p);
        }, normals);
    if (colors && k.ca)
        copy(3 * np, function(p) {
            k.dec.GetAttributeDataArrayForAllPoints(k.mesh, k.ca, D.DT_UINT8, 3 * np, p);
        }, colors, 1);
    copy(3 * nf, function(p) { k.dec.GetTrianglesUInt32Array(k.mesh, 12 * nf, p); }, triangles);
    }
    D.destroy(k.qt);
    D.destroy(k.mesh);
    D.destroy(k.dec);
});

/* Draco indexes points and corners with 32-bit ints; as draco.cpp. */
#define MAX_VERTICES (1u << 30)
#define MAX_TRIANGLES ((1u << 30) / 3)

mts_result mts_draco_decode(const uint8_t *data, size_t size, mts_draco_mesh_out *out,
                            mts_error *err)
{
    if (!out)
        return mts_error_set(err, MTS_ERR_ARG, "draco decode: NULL argument");
    memset(out, 0, sizeof *out);
    if (!data || size == 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: empty buffer");
    mts_result rc = mts_draco_check_head(data, size, err);
    if (rc != MTS_OK)
        return rc;
    uint32_t counts[4];
    float g[4];
    int bits = 0;
    char msg[256];
    if (!mts_web_draco_begin(data, size, counts, g, &bits, msg, (int)sizeof msg))
        return mts_error_set(err, MTS_ERR_FORMAT, "%s", msg);
    mts_draco_mesh_out m = {0};
    m.vertex_count = counts[0];
    m.triangle_count = counts[1];
    m.grid.bits = bits;
    memcpy(m.grid.origin, g, 12);
    m.grid.range = g[3];
    const int ok_counts = m.vertex_count > 0 && m.triangle_count > 0 &&
                          m.vertex_count <= MAX_VERTICES && m.triangle_count <= MAX_TRIANGLES;
    if (ok_counts) {
        m.positions = malloc(12 * (size_t)m.vertex_count);
        m.quantized = malloc(12 * (size_t)m.vertex_count);
        m.triangles = malloc(12 * (size_t)m.triangle_count);
        if (counts[2])
            m.normals = malloc(12 * (size_t)m.vertex_count);
        if (counts[3])
            m.colors = malloc(3 * (size_t)m.vertex_count);
    }
    const int ok_memory = ok_counts && m.positions && m.quantized && m.triangles &&
                          (!counts[2] || m.normals) && (!counts[3] || m.colors);
    /* Draco's objects go either way */
    mts_web_draco_take(ok_memory ? m.quantized : NULL, ok_memory ? m.normals : NULL,
                       ok_memory ? m.triangles : NULL, ok_memory ? m.colors : NULL);
    if (!ok_counts) {
        mts_draco_mesh_out_free(&m);
        return mts_error_set(err, m.vertex_count && m.triangle_count ? MTS_ERR_LIMIT : MTS_ERR_FORMAT,
                             "draco decode: %u points, %u faces", counts[0], counts[1]);
    }
    if (!ok_memory) {
        mts_draco_mesh_out_free(&m);
        return mts_error_set(err, MTS_ERR_NOMEM, "draco decode: out of memory (%u points)",
                             counts[0]);
    }
    if (!mts_draco_grid_valid(&m.grid)) {
        mts_draco_mesh_out_free(&m);
        return mts_error_set(err, MTS_ERR_RANGE,
                             "draco decode: bad grid (%d bits, origin %g %g %g, range %g)", bits,
                             g[0], g[1], g[2], g[3]);
    }
    const uint32_t maxq = (1u << m.grid.bits) - 1u;
    for (uint32_t i = 0; i < m.vertex_count; i++) {
        const uint32_t *q = m.quantized + 3 * (size_t)i;
        if (q[0] > maxq || q[1] > maxq || q[2] > maxq) {
            mts_draco_mesh_out_free(&m);
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "draco decode: point %u: quantized value outside the %d-bit grid",
                                 i, m.grid.bits);
        }
        mts_draco_dequantize(&m.grid, q, m.positions + 3 * (size_t)i);
        const float *n = m.normals ? m.normals + 3 * (size_t)i : NULL;
        if (n && !(isfinite(n[0]) && isfinite(n[1]) && isfinite(n[2]))) {
            mts_draco_mesh_out_free(&m);
            return mts_error_set(err, MTS_ERR_RANGE, "draco decode: point %u has no valid normal",
                                 i);
        }
    }
    for (size_t k = 0; k < 3 * (size_t)m.triangle_count; k++)
        if (m.triangles[k] >= m.vertex_count) {
            mts_draco_mesh_out_free(&m);
            return mts_error_set(err, MTS_ERR_RANGE, "draco decode: face %zu uses point %u of %u",
                                 k / 3, m.triangles[k], m.vertex_count);
        }
    *out = m;
    return MTS_OK;
}

void mts_draco_mesh_out_free(mts_draco_mesh_out *m)
{
    if (!m)
        return;
    free(m->positions);
    free(m->quantized);
    free(m->normals);
    free(m->triangles);
    free(m->colors);
    memset(m, 0, sizeof *m);
}

mts_result mts_draco_encode(const mts_draco_mesh *in, const mts_draco_options *opts,
                            uint8_t **out, size_t *size, mts_error *err)
{
    (void)in;
    (void)opts;
    (void)out;
    (void)size;
    return mts_error_set(err, MTS_ERR_ARG, "draco encode: the browser build only decodes");
}

mts_result mts_draco_renumber(const mts_draco_mesh *original, const mts_draco_mesh_out *decoded,
                              uint32_t *vertex_map, uint32_t *face_map, mts_error *err)
{
    (void)original;
    (void)decoded;
    (void)vertex_map;
    (void)face_map;
    return mts_error_set(err, MTS_ERR_ARG, "draco renumber: the browser build only decodes");
}
