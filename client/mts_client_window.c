/* mts-client --window: the window loop, one thread, never blocked by the
 * network. Each turn takes the window's and the script's input, brings the
 * view up to date, draws a frame (offscreen, blitted to the window, HUD on
 * top) and then gives the session the time left until the next frame
 * (mts_session_poll waits on the socket with that timeout and applies at
 * most a slice of frames), so batches keep arriving between frames and
 * frames keep coming while they do.
 *
 * The view (view.h) has a runtime of its own on the stream's model: the
 * stream client's runtime follows the stream, as the stream's checks need
 * (END is checked at the stop level), and the view's is what is drawn: it
 * moves to the level the user picks, touching only the strips that change,
 * with geomorphs between levels (--morph-ms). */
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>

#include "clock.h"
#include "hud.h"
#include "mts_client.h"
#include "script.h"
#include "strips.h"
#include "window.h"

/* a level change slides over this long unless --morph-ms says otherwise */
#define WIN_MORPH_MS 250.0

#define WIN_SHOTS 32

typedef struct win_shot {
    char file[300];
    uint32_t level, triangles, strips;
    char hud[512];
} win_shot;

typedef struct win {
    mts_client_run *rn;
    int quiet;             /* -q: nothing on stderr */
    mts_stream_client *c;
    mts_session_stats *st;
    mts_window *w;
    mts_hud *hud;
    mts_script script;
    int have_script;
    int manual;            /* a level key was pressed: stay at manual_level */
    uint32_t manual_level;
    int want_shot, quit, streaming, failed_stream;
    uint32_t width, height;
    double t_start, t_model; /* ms: loop start, first frame of the model (script clock) */
    /* frames per second over the last half second */
    uint64_t frames;
    uint32_t fps_frames;
    double fps_t, fps;
    win_shot shots[WIN_SHOTS];
    uint32_t shot_count;
    char hud_text[512];
    char status[200];
    int quit_early;        /* q before the stream ended */
    /* frames drawn while the stream came: from the loop's start to its end */
    uint64_t frames_streaming;
    double ms_streaming;
    /* --lod-policy other than received: what "following" means */
    const mts_lod_policy_options *po;
    mts_lod_policy policy;
    int use_policy;
    double last_frame_ms;
    /* more on demand: a stream that stopped short of the full level goes on
     * (mts_stream_client_continue) when the view asks for more */
    int fetching;            /* the stream going now is a continuation */
    uint32_t continuations;
    uint64_t bytes_before;   /* of the conversations before this one */
} win;

/* The camera as the policies see it. */
static mts_lod_view win_view(const win *wn)
{
    const mts_render_options *ro = &wn->rn->ro;
    float eye[3], dir[3], d = 0;
    mts_render_eye(wn->rn->view.renderer, eye, dir);
    for (int i = 0; i < 3; i++) {
        float cen = 0.5f * (wn->c->model.bbox_min[i] + wn->c->model.bbox_max[i]);
        d += (eye[i] - cen) * (eye[i] - cen);
    }
    mts_lod_view view = {sqrtf(d), ro->camera.fov_y_deg * 3.14159265f / 180.0f,
                         (int)ro->width, (int)ro->height};
    return view;
}

/* The level the view shows: the policy's choice -- by default "received",
 * the newest level the stream has brought -- until a level key fixes one;
 * End goes back to the policy. */
static uint32_t win_choose_level(win *wn)
{
    uint32_t available = wn->c->lod.level;
    if (wn->manual)
        return wn->manual_level < available ? wn->manual_level : available;
    if (!wn->use_policy || !wn->rn->have_view)
        return available;
    mts_lod_view view = win_view(wn);
    return mts_lod_policy_choose(&wn->policy, available, &view, wn->last_frame_ms);
}

/* What more the view asks for of a stream that ended short of the full
 * level: a level key past what came (a level stop), or the policy's
 * triangles -- the camera's for the view now, or what the frame budget
 * would take once all that came fits it -- over a tenth more than the stop
 * gave (so a small zoom does not start a conversation). 0 when nothing. */
static int win_wants_more(const win *wn, uint8_t *kind, uint32_t *value)
{
    const mts_stream_client *c = wn->c;
    if (wn->streaming || wn->failed_stream || !c->have_lod || !c->end_checksum ||
        c->stop_level >= c->info.levels || !wn->rn->have_view)
        return 0;
    if (wn->manual) {
        if (wn->manual_level <= c->stop_level)
            return 0;
        *kind = MTS_STOP_LEVEL;
        *value = wn->manual_level;
        return 1;
    }
    if (!wn->use_policy)
        return 0;
    double want;
    if (wn->po->kind == MTS_LOD_POLICY_BUDGET) {
        /* all that came fits the budget: the triangles that would */
        const mts_lod_policy *p = &wn->policy;
        if (!(p->ms_per_triangle > 0) || p->level != c->lod.level)
            return 0;
        want = p->opt.headroom * (1000.0 / p->opt.fps) / p->ms_per_triangle;
    } else {
        mts_lod_view view = win_view(wn);
        want = mts_lod_policy_view_triangles(&wn->policy, &view);
    }
    if (!(want > 1.1 * c->info.stop_triangles) || want > UINT32_MAX)
        return 0;
    *kind = MTS_STOP_TRIANGLES;
    *value = (uint32_t)want;
    return 1;
}

/* Batch boundaries: the levels after each whole batch (MODEL_INFO). */
static uint32_t win_batch_step(const win *wn, uint32_t level, int up)
{
    const mts_wire_model_info *in = &wn->c->info;
    uint32_t at = 0, best = up ? UINT32_MAX : 0;
    for (uint32_t b = 0; b <= in->batch_count; b++) {
        if (up && at > level) {
            best = at;
            break;
        }
        if (!up && at < level)
            best = at;
        if (b < in->batch_count)
            at += mts_wire_batch_splits(in, b);
    }
    return up && best == UINT32_MAX ? level : best;
}

static void win_key(win *wn, mts_key key)
{
    uint32_t cur = wn->rn->have_view ? wn->rn->view.follow.lod->level : 0;
    /* past what came only where the stream stopped short: that asks for more */
    uint32_t levels = wn->c->info.levels,
             avail = wn->c->end_checksum && !wn->failed_stream ? levels : wn->c->lod.level;
    uint32_t tenth = levels / 10 ? levels / 10 : 1;
    switch (key) {
    case MTS_KEY_PLUS:
    case MTS_KEY_MINUS:
        wn->manual = 1;
        wn->manual_level = win_batch_step(wn, cur, key == MTS_KEY_PLUS);
        break;
    case MTS_KEY_PAGE_UP:
        wn->manual = 1;
        wn->manual_level = cur + tenth < avail ? cur + tenth : avail;
        break;
    case MTS_KEY_PAGE_DOWN:
        wn->manual = 1;
        wn->manual_level = cur > tenth ? cur - tenth : 0;
        break;
    case MTS_KEY_HOME:
        wn->manual = 1;
        wn->manual_level = 0;
        break;
    case MTS_KEY_END:
        wn->manual = 0; /* the highest level received, and on as more arrive */
        break;
    case MTS_KEY_W:
        wn->rn->ro.style.wireframe = !wn->rn->ro.style.wireframe;
        if (wn->rn->have_view) /* the edges are rebuilt at the next sync */
            mts_view_set_wireframe(&wn->rn->view, wn->rn->ro.style.wireframe);
        break;
    case MTS_KEY_C:
        wn->rn->ro.style.color_by_strip = !wn->rn->ro.style.color_by_strip;
        break;
    case MTS_KEY_S:
        wn->want_shot = 1;
        break;
    case MTS_KEY_Q:
        wn->quit = 1;
        break;
    default:
        break;
    }
    if (wn->manual && wn->manual_level > avail)
        wn->manual_level = avail;
}

static int win_input(win *wn, const mts_input *ev)
{
    mts_render_camera *cam = &wn->rn->ro.camera;
    switch (ev->type) {
    case MTS_INPUT_KEY:
        win_key(wn, ev->key);
        break;
    case MTS_INPUT_DRAG: /* a window's width of drag turns the model about once */
        cam->yaw_deg -= (float)ev->dx * 0.5f;
        cam->pitch_deg += (float)ev->dy * 0.5f;
        if (cam->pitch_deg > 89)
            cam->pitch_deg = 89;
        if (cam->pitch_deg < -89)
            cam->pitch_deg = -89;
        break;
    case MTS_INPUT_SCROLL:
        cam->zoom *= powf(1.15f, (float)ev->steps);
        if (cam->zoom < 0.1f)
            cam->zoom = 0.1f;
        if (cam->zoom > 50)
            cam->zoom = 50;
        break;
    case MTS_INPUT_RESIZE:
        if (ev->width < 1 || ev->height < 1)
            break;
        wn->width = ev->width;
        wn->height = ev->height;
        wn->rn->ro.width = ev->width;
        wn->rn->ro.height = ev->height;
        if (wn->rn->have_view &&
            mts_render_resize(wn->rn->view.renderer, ev->width, ev->height, &wn->rn->err))
            return 0;
        break;
    case MTS_INPUT_CLOSE:
        wn->quit = 1;
        break;
    default:
        break;
    }
    return 1;
}

static int win_on_event(void *user, mts_stream_event ev, mts_stream_client *c)
{
    win *wn = user;
    mts_client_run *rn = wn->rn;
    if (ev == MTS_EV_RESUMED && !wn->quiet && !wn->fetching)
        fprintf(stderr, "mts-client: reconnected; resuming at batch %u of %u\n", c->batches,
                c->info.batch_count);
    if (ev == MTS_EV_BASE && !rn->have_view) {
        /* the budget policy reads frame times: those need a finished frame */
        rn->ro.timed = wn->po->kind == MTS_LOD_POLICY_BUDGET;
        mts_view_options vo = {1, rn->morph_ms >= 0 ? rn->morph_ms : WIN_MORPH_MS, 0};
        if (!mts_client_run_make_view(rn, c, &vo))
            return 1;
        mts_view_set_wireframe(&rn->view, rn->ro.style.wireframe);
        if (wn->po->kind != MTS_LOD_POLICY_RECEIVED) { /* it frames the model's box */
            mts_lod_policy_init(&wn->policy, wn->po, &c->model);
            mts_strip_stats base = {0};
            mts_strips_stats(&c->model.base, &base);
            mts_lod_policy_set_counts(&wn->policy, (uint32_t)base.triangles, c->info.triangles);
            wn->use_policy = 1;
        }
    }
    return 0;
}

/* Brings the view up to the stream and towards the chosen level. */
static int win_sync(win *wn, double now)
{
    mts_client_run *rn = wn->rn;
    if (!rn->have_view)
        return 1;
    mts_follow_source src = mts_follow_source_of_stream(wn->c);
    return mts_view_sync(&rn->view, &src, win_choose_level(wn), now, &rn->err) == MTS_OK;
}

static void win_hud_text(win *wn, double now)
{
    const mts_stream_client *c = wn->c;
    const mts_session_stats *st = wn->st;
    double secs = st->ms_final > 0 ? st->ms_final / 1e3 : (now - wn->t_start) / 1e3;
    uint64_t bytes = wn->bytes_before + st->bytes;
    double mbs = secs > 0 ? (double)st->bytes / secs / 1e6 : 0;
    const char *state = wn->failed_stream                 ? wn->status
                        : wn->streaming && wn->fetching   ? "fetching"
                        : wn->streaming                   ? "streaming"
                        : c->stop_level < c->info.levels ? "complete to here (zoom in for more)"
                                                          : "complete";
    const mts_follow *v = &wn->rn->view.follow;
    if (!wn->rn->have_view || !v->have_figures) {
        snprintf(wn->hud_text, sizeof wn->hud_text,
                 "%s  waiting for the base mesh\n%.1f frames/s  %llu bytes  %.2f MB/s  %s",
                 wn->rn->model, wn->fps, (unsigned long long)bytes, mbs, state);
        return;
    }
    char morph[64] = "morph off";
    if (v->opts.morph_ms > 0)
        snprintf(morph, sizeof morph,
                 v->morph.active ? "morphing %.0f ms (%.0f%%)" : "morph %.0f ms", v->opts.morph_ms,
                 100.0 * v->morph.t);
    snprintf(wn->hud_text, sizeof wn->hud_text,
             "%s  level %u of %u (received %u, %s)\n"
             "triangles %u  strips %u  indices/triangle %.2f  %s\n"
             "%.1f frames/s  %llu bytes  %.2f MB/s  %s\n"
             "+/- batch  PgUp/PgDn 10%%  Home/End  w wire  c colour  s shot  q quit",
             wn->rn->model, v->shown.level, c->info.levels, c->lod.level,
             wn->manual ? "fixed" : "following", v->shown.triangles, v->shown.strips,
             v->shown.triangles ? (double)v->shown.indices / v->shown.triangles : 0.0, morph,
             wn->fps, (unsigned long long)bytes, mbs, state);
}

static int win_frame(win *wn, double now)
{
    mts_client_run *rn = wn->rn;
    win_hud_text(wn, now);
    int scale = wn->width >= 1000 ? 2 : 1;
    mts_renderer *r = rn->have_view ? rn->view.renderer : NULL;
    if (r && rn->view.follow.have_figures) {
        double t = (1e3 * mts_clock_seconds());
        mts_render_set_camera(r, &rn->ro.camera);
        mts_render_set_style(r, &rn->ro.style);
        if (mts_view_draw(&rn->view, &rn->err) != MTS_OK || mts_render_blit(r, &rn->err))
            return 0;
        wn->last_frame_ms = (1e3 * mts_clock_seconds()) - t;
        rn->ms_render += wn->last_frame_ms;
        if (wn->t_model == 0)
            wn->t_model = (1e3 * mts_clock_seconds()); /* the script's clock starts at the first picture */
    } else {
        if (mts_hud_clear(wn->hud, rn->ro.style.background, wn->width, wn->height, &rn->err))
            return 0;
    }
    if (mts_hud_draw(wn->hud, wn->hud_text, wn->width, wn->height, scale, &rn->err) != MTS_OK ||
        mts_render_context_swap(rn->ctx, &rn->err) != MTS_OK)
        return 0;
    wn->frames++;
    wn->fps_frames++;
    if (now - wn->fps_t >= 500) {
        wn->fps = wn->fps_frames * 1e3 / (now - wn->fps_t);
        wn->fps_frames = 0;
        wn->fps_t = now;
    }
    if (wn->want_shot && r && rn->view.follow.have_figures) {
        const mts_follow *v = &rn->view.follow;
        wn->want_shot = 0;
        char path[300];
        if (v->morph.active) /* a frame between two levels: say so in its name */
            snprintf(path, sizeof path, "%s_L%u_morph%02.0f.png", rn->model, v->shown.level,
                     100.0 * v->morph.t);
        else
            snprintf(path, sizeof path, "%s_L%u.png", rn->model, v->shown.level);
        if (mts_render_write_png(r, path, &rn->err) != MTS_OK)
            return 0;
        if (wn->shot_count < WIN_SHOTS) {
            win_shot *s = &wn->shots[wn->shot_count++];
            snprintf(s->file, sizeof s->file, "%s", path);
            s->level = v->shown.level;
            s->triangles = v->shown.triangles;
            s->strips = v->shown.strips;
            snprintf(s->hud, sizeof s->hud, "%s", wn->hud_text);
        }
        if (!wn->quiet)
            fprintf(stderr, "mts-client: wrote %s (level %u, %u triangles)\n", path,
                    v->shown.level, v->shown.triangles);
    }
    return 1;
}

/* The figures of the frames drawn while the stream came, taken once as it
 * ends (completed, failed or quit). */
static void win_stream_ended(win *wn)
{
    wn->frames_streaming = wn->frames;
    wn->ms_streaming = (1e3 * mts_clock_seconds()) - wn->t_start;
}

/* Runs the window until q (or the close button). Returns the session's
 * result; *wn keeps what the summary needs. */
static mts_result win_run(win *wn, mts_session_options *so, const char *script_path,
                          const mts_lod_policy_options *po, mts_error *err)
{
    mts_client_run *rn = wn->rn;
    mts_result rc = MTS_OK;
    wn->po = po;
    if (script_path) {
        if ((rc = mts_script_load(script_path, &wn->script, err)) != MTS_OK)
            return rc;
        wn->have_script = 1;
    }
    wn->width = rn->ro.width;
    wn->height = rn->ro.height;
    char title[200];
    snprintf(title, sizeof title, "mts-client: %s", rn->model);
    if ((rc = mts_window_create(title, wn->width, wn->height, &wn->w, err)) != MTS_OK ||
        (rc = mts_render_context_create_window(mts_window_native_display(wn->w),
                                               mts_window_native_window(wn->w), &rn->ctx,
                                               err)) != MTS_OK ||
        (rc = mts_hud_create(rn->ctx, &wn->hud, err)) != MTS_OK)
        return rc;
    if (!mts_client_run_warm_up(rn)) {
        *err = rn->err;
        return err->code ? err->code : MTS_ERR_INTERNAL;
    }
    so->on_event = win_on_event;
    so->user = wn;
    /* no retry lines from the window: win_on_event says when the stream
     * resumes, and the HUD what it is doing */
    so->on_retry = NULL;
    mts_session *sess;
    if ((rc = mts_session_begin(so, wn->c, wn->st, &sess, err)) != MTS_OK)
        return rc;
    wn->streaming = 1;
    wn->t_start = wn->fps_t = (1e3 * mts_clock_seconds());
    const double frame_ms = 1000.0 / 60;
    double next_frame = (1e3 * mts_clock_seconds());
    while (!wn->quit) {
        double now = (1e3 * mts_clock_seconds());
        mts_input ev;
        int ok = 1;
        while (ok && mts_window_poll(wn->w, &ev))
            ok = win_input(wn, &ev);
        while (ok && wn->have_script && wn->t_model > 0 &&
               mts_script_next(&wn->script, (now - wn->t_model) / 1e3, &ev))
            ok = win_input(wn, &ev);
        if (ok && !win_sync(wn, now))
            ok = 0;
        if (ok && !win_frame(wn, now))
            ok = 0;
        if (!ok || rn->failed) { /* GL or the display runtime: nothing more to show */
            if (wn->streaming)
                mts_session_end(sess, NULL);
            wn->streaming = 0;
            *err = rn->err;
            return err->code ? err->code : MTS_ERR_INTERNAL;
        }
        /* the network gets the time until the next frame */
        next_frame += frame_ms;
        if (next_frame < (1e3 * mts_clock_seconds()))
            next_frame = (1e3 * mts_clock_seconds());
        for (;;) {
            double left = next_frame - (1e3 * mts_clock_seconds());
            uint8_t kind;
            uint32_t value;
            if (!wn->streaming && win_wants_more(wn, &kind, &value)) {
                /* more on demand: the same stream from the batches held,
                 * to the new stop (PROTOCOL.md, "Continuing") */
                uint32_t batch;
                uint64_t id;
                if ((rc = mts_stream_client_continue(wn->c, &batch, &id, err)) != MTS_OK)
                    return rc;
                so->hello.stop_kind = kind;
                so->hello.stop_value = value;
                so->hello.resume_batch = batch;
                so->hello.stream_id = id;
                wn->bytes_before += wn->st->bytes;
                if ((rc = mts_session_begin(so, wn->c, wn->st, &sess, err)) != MTS_OK)
                    return rc;
                wn->streaming = wn->fetching = 1;
                wn->continuations++;
            }
            if (!wn->streaming) {
                if (left > 0) {
                    struct pollfd pf = {mts_window_fd(wn->w), POLLIN, 0};
                    poll(&pf, 1, (int)left);
                }
                break;
            }
            wn->streaming = mts_session_poll(sess, left > 0 ? (int)left : 0);
            if (!wn->streaming) {
                if (!wn->fetching)
                    win_stream_ended(wn);
                wn->fetching = 0;
                rc = mts_session_end(sess, err);
                if (rc != MTS_OK) {
                    /* the window stays up with the last whole batch; q ends it */
                    wn->failed_stream = 1;
                    snprintf(wn->status, sizeof wn->status, "stopped: %.180s", err->msg);
                    if (!wn->quiet)
                        fprintf(stderr, "mts-client: %s\n", err->msg);
                }
            }
            if (left <= 0 || rn->failed)
                break;
        }
    }
    if (wn->streaming) { /* quit before the end: the user's choice, not a failure */
        mts_session_end(sess, NULL);
        wn->streaming = 0;
        wn->quit_early = 1;
        win_stream_ended(wn);
    }
    return rc;
}

static void win_free(win *wn)
{
    mts_hud_destroy(wn->hud);
    mts_script_free(&wn->script);
}

int client_window_main(client_options *o)
{
    mts_client_run *rn = &o->run;
    mts_session_options *so = &o->so;
    const mts_lod_policy_options *po = &rn->po;
    win wn;
    memset(&wn, 0, sizeof wn);
    mts_stream_client c;
    mts_stream_client_init(&c);
    c.threads = rn->threads;
    mts_session_stats st;
    memset(&st, 0, sizeof st);
    wn.rn = rn;
    wn.quiet = o->quiet;
    wn.c = &c;
    wn.st = &st;
    mts_error err = {0};
    /* the camera policies ask for their level's stop, as headless; zooming
     * in then asks for more (win_wants_more) */
    mts_client_run_stop stop = {0};
    if (so->hello.stop_kind == MTS_STOP_FULL && po->kind != MTS_LOD_POLICY_RECEIVED)
        mts_client_run_policy_stop(so, rn, 1.0 / rn->ro.camera.zoom, &stop);
    mts_result rc = win_run(&wn, so, o->script, po, &err);
    if (rn->failed && rc == MTS_OK) {
        rc = rn->err.code ? rn->err.code : MTS_ERR_INTERNAL;
        err = rn->err;
    }
    int complete = rc == MTS_OK && !wn.quit_early;
    if (o->json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        mts_client_run_json_head(&j, rn, &c, complete, wn.bytes_before + st.bytes);
        mts_client_run_json(&j, &c, &st, rn);
        cli_json_num(&j, "morph_ms", rn->have_view ? rn->view.follow.opts.morph_ms : 0, 1);
        cli_json_u64(&j, "frames", wn.frames);
        /* conversations that went on past the stop because the view asked */
        cli_json_u64(&j, "continuations", wn.continuations);
        /* while the stream came (the loop's start to its end): frames/s then */
        cli_json_u64(&j, "frames_streaming", wn.frames_streaming);
        cli_json_num(&j, "seconds_streaming", wn.ms_streaming / 1e3, 3);
        cli_json_num(&j, "fps_streaming",
                     wn.ms_streaming > 0 ? wn.frames_streaming * 1e3 / wn.ms_streaming : 0, 1);
        if (po->kind != MTS_LOD_POLICY_RECEIVED)
            cli_json_str(&j, "lod_policy", mts_lod_policy_name(po->kind));
        cli_json_u64(&j, "level_shown", rn->have_view ? rn->view.follow.shown.level : 0);
        /* each screenshot with the figures its frame's HUD showed, and the HUD text */
        cli_json_key(&j, "screenshots");
        fputc('[', stdout);
        for (uint32_t i = 0; i < wn.shot_count; i++) {
            const win_shot *s = &wn.shots[i];
            fprintf(stdout, "%s{\"file\":\"", i ? "," : "");
            cli_json_text(stdout, s->file);
            fprintf(stdout, "\",\"level\":%u,\"triangles\":%u,\"strips\":%u,\"hud\":\"",
                    s->level, s->triangles, s->strips);
            cli_json_text(stdout, s->hud);
            fputs("\"}", stdout);
        }
        fputc(']', stdout);
        if (rc != MTS_OK)
            cli_json_str(&j, "error", err.msg);
        cli_json_end(&j);
    } else if (!o->quiet && c.have_lod) {
        printf("%s: level %u of %u received, %u triangles, %u batches, %llu bytes; %llu frames "
               "shown%s\n",
               rn->model, c.lod.level, c.info.levels, mts_client_run_triangles(&c), c.batches,
               (unsigned long long)(wn.bytes_before + st.bytes), (unsigned long long)wn.frames,
               wn.quit_early ? " (quit before the end of the stream)" : "");
        for (uint32_t i = 0; i < wn.shot_count; i++)
            printf("  wrote %s\n", wn.shots[i].file);
    }
    /* a stream error was said as it happened; the rest now */
    if (rc != MTS_OK && !wn.failed_stream)
        fprintf(stderr, "mts-client: %s\n", err.msg);
    win_free(&wn);
    mts_client_run_free(rn); /* its EGL surface before the window under it */
    mts_window_destroy(wn.w);
    mts_stream_client_free(&c);
    return rc == MTS_OK ? CLI_EXIT_OK : CLI_EXIT_FAIL;
}

