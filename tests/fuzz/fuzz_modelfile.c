/* Fuzz target: the model-file loader, mts_modelfile_decode.
 *
 * Input: one mode byte, then the file's bytes.
 *   bit 0  1: leave the header and section CRCs as they are; 0: rewrite them
 *          first, so that mutations reach the section parsers and
 *          mts_model_validate behind the checksums
 * A model that loads was validated, and everything downstream trusts that
 * (mts_lod collapses check nothing; the server streams it): so a loaded model
 * is walked from the full level to the base and back, from the base up, in
 * slots as long as its capacities (which no strip may pass at any level,
 * though they may pass the full strips), and encoded and loaded again, which
 * must all work. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "lod.h"
#include "model.h"
#include "modelfile.h"

/* The runtime's slots are the capacities, and every strip fits its slot. */
static void mts_fuzz_check_slots(const mts_model *m, const mts_lod *lod)
{
    MTS_FUZZ_CHECK(lod->slot[0] == 0);
    for (uint32_t s = 0; s < m->strip_count; s++) {
        MTS_FUZZ_CHECK(lod->slot[s + 1] - lod->slot[s] == m->capacity[s]);
        MTS_FUZZ_CHECK(lod->length[s] <= m->capacity[s]);
    }
}

static void mts_fuzz_walk_model(const mts_model *m)
{
    mts_error err = {0};
    mts_lod lod;
    MTS_FUZZ_CHECK(m->strip_count == 0 || m->capacity != NULL);
    MTS_FUZZ_CHECK(mts_lod_init(&lod, m, MTS_LOD_AT_FULL, &err) == MTS_OK);
    mts_fuzz_check_slots(m, &lod);
    /* one level at a time, each checked against the capacities */
    while (lod.level > 0) {
        mts_lod_collapse(&lod);
        mts_fuzz_check_slots(m, &lod);
    }
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, s, &len);
        MTS_FUZZ_CHECK(len == m->base.offsets[s + 1] - m->base.offsets[s]);
        MTS_FUZZ_CHECK(memcmp(str, m->base.indices + m->base.offsets[s], (size_t)len * 4) == 0);
    }
    mts_lod_free(&lod);
    MTS_FUZZ_CHECK(mts_lod_init(&lod, m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    MTS_FUZZ_CHECK(mts_lod_set_level(&lod, m->level_count, &err) == MTS_OK);
    mts_fuzz_check_slots(m, &lod);
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, s, &len);
        MTS_FUZZ_CHECK(len == m->full.offsets[s + 1] - m->full.offsets[s]);
        MTS_FUZZ_CHECK(memcmp(str, m->full.indices + m->full.offsets[s], (size_t)len * 4) == 0);
    }
    mts_lod_free(&lod);

    uint8_t *again = NULL;
    size_t again_size = 0;
    MTS_FUZZ_CHECK(mts_modelfile_encode(m, &again, &again_size, &err) == MTS_OK);
    mts_model m2;
    MTS_FUZZ_CHECK(mts_modelfile_decode(again, again_size, "again", &m2, &err) == MTS_OK);
    MTS_FUZZ_CHECK(m2.vertex_count == m->vertex_count && m2.level_count == m->level_count &&
                   m2.record_word_count == m->record_word_count &&
                   m2.strip_count == m->strip_count);
    MTS_FUZZ_CHECK(m->strip_count == 0 ||
                   memcmp(m2.capacity, m->capacity, (size_t)m->strip_count * 4) == 0);
    mts_model_free(&m2);
    free(again);
}

int mts_fuzz_modelfile(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const uint8_t mode = data[0];
    size--;
    /* an exact-size copy, so ASan sees any read past the file */
    uint8_t *bytes = malloc(size ? size : 1);
    MTS_FUZZ_CHECK(bytes != NULL);
    memcpy(bytes, data + 1, size);
    if (!(mode & 1))
        mts_fuzz_fix_modelfile_crcs(bytes, size);
    mts_model m;
    mts_error err = {0};
    mts_result rc = mts_modelfile_decode(bytes, size, "fuzz.mtsm", &m, &err);
    if (rc == MTS_OK) {
        mts_fuzz_walk_model(&m);
        mts_model_free(&m);
    } else {
        MTS_FUZZ_CHECK(err.msg[0] != 0 && err.code == rc);
        /* a failed load leaves nothing to free */
        MTS_FUZZ_CHECK(m.positions == NULL && m.record_data == NULL && m.full.indices == NULL &&
                       m.capacity == NULL);
    }
    free(bytes);
    return 0;
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_modelfile(data, size);
}
#endif
