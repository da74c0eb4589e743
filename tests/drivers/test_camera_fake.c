/* test_camera_fake.c - drivers/camera's "fake" backend: Aravis's
 * in-process fake camera driven by the aravis backend's operations, its
 * pixels from the simulator (mocks/camsrc/fakesrc.h) attached in-process
 * or loaded from bin/specklab-fake-source.so as specklabd does.  No
 * network: no namespace, no port, so these run anywhere and in parallel.
 *
 * Each test runs in a forked child (a fresh Aravis and GLib), its verdict
 * read with a deadline.  Pixel truth: camtruth_fx.h re-renders each frame
 * from fakecam.h's model and compares it bit for bit.
 */
#define _GNU_SOURCE
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "fakesrc.h"
#include "proc_fx.h"
#include "tcheck.h"
#include "camtruth_fx.h"

/* camtruth_fx.h's camera: 80x72 sensor, seed 11, screen slot 3. */
#define SRC_ARGS "--size 80x72 --seed 11 --screen-slot 3"

/* The fake camera with the simulator attached in-process (lib NULL) or
 * loaded from lib; configured and started as camtruth_open does. */
static int fake_open(camera **c, const char *lib, double fps, int nbuf, char *err, size_t n)
{
    sl_err e = {0};
    camera_source src;
    int rc = camera_open(c, "fake", "Fake_1", &e);
    if (rc != SL_OK)
        return snprintf(err, n, "open: %.400s", e.msg), -1;
    if (lib) {
        rc = camera_load_source(*c, lib, SRC_ARGS);
    } else if ((rc = fakesrc_new(&src, SRC_ARGS, &e)) != SL_OK) {
        return snprintf(err, n, "fakesrc_new: %.400s", e.msg), -1;
    } else if ((rc = camera_set_source(*c, &src)) != SL_OK) {
        src.release(src.data);
    }
    if (rc != SL_OK)
        return snprintf(err, n, "source: %s", camera_errmsg(*c)), -1;
    return camtruth_configure(*c, fps, nbuf, err, n);
}

/* Pop n frames into pix (one slot); count SUCCESS frames, frames not the
 * simulator's and breaks in the id sequence.  -1 on a pop error. */
static int pop_check(camera *c, truth *tr, uint16_t *pix, int n, int *good, int *wrong,
                     int *jumps, char *err, size_t en)
{
    uint64_t prev = 0;
    for (int i = 0; i < n; i++) {
        camera_frame f;
        if (camtruth_pop(c, pix, 2000, &f, 0, err, en) != SL_OK)
            return -1;
        /* Block ids run 1..65535 as on GigE Vision (the fake starts
         * near the wrap, so a run of a few hundred frames crosses it). */
        *jumps += i > 0 && f.frame_id != (prev == 65535 ? 1 : prev + 1);
        prev = f.frame_id;
        if (f.status == CAMERA_FRAME_SUCCESS)
            ++*good, *wrong += truth_diff(tr, f.frame_id, pix) != 0;
    }
    return 0;
}

/* 500 frames at 500 Hz: every one SUCCESS, ids consecutive (across the
 * wrap), pixels the simulator's, counted once; speckle, not a dark or ramp frame. */
static void body_frames(tc *t)
{
    enum { N = 500 };
    static truth tr;
    static uint16_t pix[NPX];
    char err[512] = "";
    camera *c = NULL;
    camera_info info = {0};
    camera_stats st = {0};
    int good = 0, wrong = 0, jumps = 0, rc = truth_new(&tr, 3, 10000, 0, err, sizeof err);
    if (rc == 0)
        rc = fake_open(&c, NULL, 500, 64, err, sizeof err);
    if (rc == 0 && camera_info_get(c, &info) != SL_OK)
        rc = -1, snprintf(err, sizeof err, "%s", camera_errmsg(c));
    if (rc == 0)
        rc = pop_check(c, &tr, pix, N, &good, &wrong, &jumps, err, sizeof err);
    uint16_t lo = 65535, hi = 0;
    for (size_t i = 0; i < NPX; i++)
        lo = pix[i] < lo ? pix[i] : lo, hi = pix[i] > hi ? pix[i] : hi;
    if (c)
        camera_stats_get(c, &st);
    camera_close(c);
    truth_free(&tr);
    CHECK(rc == 0, "%s", err);
    CHECK(!strcmp(info.protocol, "Fake") && !strcmp(info.address, "Fake_1"), "info: %s %s",
          info.protocol, info.address);
    CHECK(good == N && wrong == 0, "%d of %d SUCCESS, %d not the simulator's", good, N, wrong);
    CHECK(jumps == 0 && st.id_gaps == 0, "%d jumps in the ids (%llu gaps)", jumps,
          (unsigned long long)st.id_gaps);
    CHECK(st.completed == N && st.failed == 0, "stats %llu + %llu",
          (unsigned long long)st.completed, (unsigned long long)st.failed);
    CHECK(hi > 150 && lo < 150, "the last frame is flat (%u..%u ADU, bias 100)", lo, hi);
}

/* The shared object specklabd loads gives the same pixels; a reconnect
 * gets a fresh fake camera, attaches the source again and re-applies the
 * settings (ROI, exposure): the frames after it are still the
 * simulator's, at the new exposure. */
static void body_library_reconnect(tc *t)
{
    static truth tr, bright;
    static uint16_t pix[NPX];
    char err[512] = "", lib[PATH_MAX];
    camera *c = NULL;
    camera_config cf = {0};
    camera_stats st = {0};
    int good = 0, wrong = 0, jumps = 0, good2 = 0, wrong2 = 0;
    fx_bin(lib, sizeof lib, "specklab-fake-source.so");
    int rc = truth_new(&tr, 3, 10000, 0, err, sizeof err);
    if (rc == 0)
        rc = truth_new(&bright, 3, 20000, 0, err, sizeof err);
    if (rc == 0)
        rc = fake_open(&c, lib, 200, 16, err, sizeof err);
    if (rc == 0)
        rc = pop_check(c, &tr, pix, 20, &good, &wrong, &jumps, err, sizeof err);
    if (rc == 0 && (camera_stop(c) != SL_OK || camera_set_exposure_us(c, 20000) != SL_OK ||
                    camera_start(c, 16) != SL_OK || camera_reconnect(c, 5000) != SL_OK ||
                    camera_config_get(c, &cf) != SL_OK))
        rc = -1, snprintf(err, sizeof err, "%s", camera_errmsg(c));
    if (rc == 0)
        rc = pop_check(c, &bright, pix, 20, &good2, &wrong2, &jumps, err, sizeof err);
    if (c)
        camera_stats_get(c, &st);
    camera_close(c);
    truth_free(&tr);
    truth_free(&bright);
    CHECK(rc == 0, "%s (library %s)", err, lib);
    CHECK(good == 20 && wrong == 0, "before: %d good, %d not the simulator's", good, wrong);
    CHECK(cf.width == ROI_W && cf.height == ROI_H && cf.x == ROI_X && cf.exposure_us == 20000,
          "after the reconnect: ROI %d,%d %dx%d, exposure %g", cf.x, cf.y, cf.width, cf.height,
          cf.exposure_us);
    CHECK(good2 == 20 && wrong2 == 0, "after: %d good, %d not the simulator's at 20 ms",
          good2, wrong2);
    CHECK(st.reconnects == 1 && st.completed == 40 && st.failed == 0,
          "stats: %llu reconnects, %llu + %llu", (unsigned long long)st.reconnects,
          (unsigned long long)st.completed, (unsigned long long)st.failed);
}

/* A good frame that does not fit the caller's buffer is SL_ERANGE,
 * SIZE_MISMATCH, counted failed, and writes no pixel; the next one that
 * fits is good. */
static void body_too_small(tc *t)
{
    static truth tr;
    static uint16_t pix[NPX];
    char err[512] = "";
    camera *c = NULL;
    camera_stats st = {0};
    int rc = truth_new(&tr, 3, 10000, 0, err, sizeof err), rsmall = 0, untouched = 1;
    int good = 0, wrong = 0, jumps = 0;
    camera_frame f = {.u16 = pix, .capacity_px = NPX / 2};
    if (rc == 0)
        rc = fake_open(&c, NULL, 200, 16, err, sizeof err);
    if (rc == 0) {
        memset(pix, 0xAB, sizeof pix);
        rsmall = camera_pop(c, 2000, &f);
        for (size_t i = 0; i < NPX; i++)
            untouched &= pix[i] == 0xABAB;
        rc = pop_check(c, &tr, pix, 5, &good, &wrong, &jumps, err, sizeof err);
    }
    if (c)
        camera_stats_get(c, &st);
    camera_close(c);
    truth_free(&tr);
    CHECK(rc == 0, "%s", err);
    CHECK(rsmall == SL_ERANGE && f.status == CAMERA_FRAME_SIZE_MISMATCH, "half a buffer: %d, %s",
          rsmall, camera_frame_status_name(f.status));
    CHECK(untouched, "a frame that did not fit wrote pixels");
    CHECK(good == 5 && wrong == 0, "then %d good, %d wrong", good, wrong);
    CHECK(st.failed == 1 && st.completed == 5 &&
          st.by_status[CAMERA_FRAME_SIZE_MISMATCH] == 1, "stats %llu + %llu",
          (unsigned long long)st.completed, (unsigned long long)st.failed);
}

/* Listing finds the fake device; the backend opens nothing else, feeds
 * nothing without attach, and names a missing library. */
static void body_list_and_refusals(tc *t)
{
    camera_info *v = NULL;
    camera *c = NULL;
    sl_err e = {0}, e2 = {0};
    int n = 0, found = 0;
    int rl = camera_list("fake", &v, &n, &e);
    for (int i = 0; i < n; i++)
        found += !strcmp(v[i].id, "Fake_1") && !strcmp(v[i].protocol, "Fake");
    free(v);
    int rbad = camera_open(&c, "fake", "NoSuchCamera", &e2);
    camera_close(c);
    c = NULL;
    int ropen = camera_open(&c, "fake", "Fake_1", &e);
    int rnull = ropen == SL_OK ? camera_set_source(c, &(camera_source){0}) : 0;
    int rlib = ropen == SL_OK ? camera_load_source(c, "/nonexistent/src.so", "") : 0;
    char mlib[SL_ERRMSG_MAX];
    snprintf(mlib, sizeof mlib, "%s", camera_errmsg(c));
    camera_close(c);
    CHECK(rl == SL_OK && found == 1, "camera_list: %d, %d devices, Fake_1 found %d", rl, n, found);
    CHECK(rbad != SL_OK, "the fake backend opened 'NoSuchCamera'");
    CHECK(ropen == SL_OK, "open Fake_1: %s", e.msg);
    CHECK(rnull == SL_EINVAL, "a source without attach gave %d", rnull);
    CHECK(rlib != SL_OK && strstr(mlib, "/nonexistent/src.so"), "missing library: %d %s", rlib,
          mlib);
}

TEST(frames_match_simulator) { fx_in_child(t, body_frames, 60); }
TEST(library_source_and_reconnect) { fx_in_child(t, body_library_reconnect, 60); }
TEST(too_small_never_written) { fx_in_child(t, body_too_small, 60); }
TEST(list_and_refusals) { fx_in_child(t, body_list_and_refusals, 60); }

TC_MAIN(TC_CASE(frames_match_simulator), TC_CASE(library_source_and_reconnect),
        TC_CASE(too_small_never_written), TC_CASE(list_and_refusals))
