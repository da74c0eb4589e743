/* test_stream_ahead.c - a pass read ahead before it is fed
 * (pipeline_int.h, stream_prefetch): the pass that follows takes the
 * readers over and gets the frames in order, as a serial pass reads them;
 * readers no pass takes are stopped by stream_close; readers started for
 * another range are dropped and the pass reads its own. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/cube.h"
#include "pipeline/pipeline_int.h"
#include "tcheck.h"

enum { W = 48, H = 40, NF = 37 };

/* The frames a pass fed: a hash of each, in the order fed. */
typedef struct seen {
    int n;
    uint64_t hash[NF];
} seen;

static int record(void *h, const float *frame)
{
    seen *s = h;
    uint64_t x = 1469598103934665603ull;
    const unsigned char *b = (const unsigned char *)frame;
    for (size_t i = 0; i < sizeof(float) * W * H; i++)
        x = (x ^ b[i]) * 1099511628211ull;
    if (s->n < NF)
        s->hash[s->n] = x;
    s->n++;
    return SL_OK;
}

static int write_cube(const char *path)
{
    cube_writer *w = NULL;
    float f[W * H];
    int rc = cube_writer_open(&w, path, W, H, -32, NULL, NULL);
    for (int k = 0; rc == SL_OK && k < NF; k++) {
        for (int i = 0; i < W * H; i++)
            f[i] = (float)((i * 7 + k * 13) % 29 + k);
        rc = cube_writer_append(w, f);
    }
    if (rc == SL_OK)
        rc = cube_writer_close(w);
    cube_writer_free(w);
    return rc;
}

/* s opened on path with `threads` threads (the cleaning on or off). */
static int open_stream(stream *s, const char *path, int threads, int clean)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.nthreads = threads, o.prep = clean, o.fftw_measure = 0;
    const char *paths[] = {path};
    memset(s, 0, sizeof *s);
    return stream_open(s, paths, 1, &o, NULL);
}

TEST(prefetched_pass_is_taken_over_or_stopped)
{
    char dir[] = "/tmp/sl_aheadXXXXXX", path[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(path, sizeof path, "%s/c.fits", dir);
    CHECK(write_cube(path) == SL_OK, "writing %s", path);
    static const int threads[] = {2, 9}; /* one reader, three */
    for (int p = 0; p < 2; p++)
        for (int i = 0; i < 2; i++) {
            stream s;
            if (open_stream(&s, path, threads[i], p) != SL_OK) {
                CHECK(0, "stream_open, %d threads", threads[i]);
                continue;
            }
            seen ref = {0}, got = {0}, part = {0};
            s.ahead = 0; /* the serial pass */
            CHECK(stream_feed(&s, record, &ref, "ref", NULL) == SL_OK && ref.n == NF,
                  "serial pass: %d frames", ref.n);
            s.ahead = 1;
            stream_prefetch(&s);
            CHECK(s.pre, "%d threads: no readers started", threads[i]);
            CHECK(stream_feed(&s, record, &got, "ahead", NULL) == SL_OK && got.n == NF &&
                      memcmp(got.hash, ref.hash, sizeof ref.hash) == 0 && !s.pre,
                  "%d threads, prep %d: the prefetched pass fed %d frames, not the "
                  "serial pass's", threads[i], p, got.n);
            stream_prefetch(&s); /* then a pass over another range */
            s.k0 = 5;
            CHECK(stream_feed(&s, record, &part, "part", NULL) == SL_OK &&
                      part.n == NF - 5 &&
                      memcmp(part.hash, ref.hash + 5, sizeof(uint64_t) * (NF - 5)) == 0,
                  "%d threads: from frame 5, %d frames, not frames 5..", threads[i], part.n);
            s.k0 = 0;
            stream_prefetch(&s); /* taken by no pass: stream_close stops it */
            stream_close(&s);
            CHECK(!s.pre, "readers left after close");
        }
    unlink(path);
    rmdir(dir);
}

TC_MAIN(TC_CASE(prefetched_pass_is_taken_over_or_stopped))
