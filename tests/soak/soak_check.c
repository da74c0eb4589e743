/* soak_check.c - the soak's verdict on what the daemon left: cubes read
 * with cfitsio, checksums with GChecksum, the catalogue through a handle
 * of the soak's own (after PRAGMA integrity_check) - never through the
 * daemon's word alone. */
#include "daemon_fx.h"

#include <dirent.h>   /* after daemon_fx.h: it sets _GNU_SOURCE */
#include "soak.h"

void soak_problem(soak *s, const char *fmt, ...)
{
    va_list ap;
    char msg[1024];
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    s->nproblems++;
    if (s->nproblems <= 40)
        g_string_append_printf(s->problems, "  - %s\n", msg);
    printf("soak: PROBLEM: %s\n", msg);
    fflush(stdout);
}

/* Streamed: the long run's cube is hundreds of MB. */
static int sha256_file(const char *path, char hex[65])
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    GChecksum *ck = g_checksum_new(G_CHECKSUM_SHA256);
    guchar *buf = g_malloc(1 << 20);
    size_t n;
    while ((n = fread(buf, 1, 1 << 20, f)) > 0)
        g_checksum_update(ck, buf, (gssize)n);
    int rc = ferror(f) ? -1 : 0;
    snprintf(hex, 65, "%s", g_checksum_get_string(ck));
    g_free(buf);
    g_checksum_free(ck);
    fclose(f);
    return rc;
}

/* The driver's own rule (camera_aravis_stream.c): GigE Vision 1 block ids
 * cycle 1..65535, distances taken modulo 65535, forward under half the
 * cycle; a late (out-of-order) frame fills a gap back in.  Ids 0 (leader
 * lost) are not tracked. */
static long id_gaps(const LONGLONG *ids, long n, GString *where)
{
    long gaps = 0, shown = 0;
    LONGLONG last = 0;
    int have = 0;
    for (long i = 0; i < n; i++) {
        if (ids[i] == 0)
            continue;
        if (!have) {
            last = ids[i], have = 1;
            continue;
        }
        long long d = ids[i] - last;
        if (last >= 1 && last <= 65535 && ids[i] >= 1 && ids[i] <= 65535) {
            d %= 65535;
            d += d < 0 ? 65535 : 0;
            d = d > 32767 ? d - 65535 : d;
        }
        if (d > 1 && shown++ < 6)   /* where: for the report */
            g_string_append_printf(where, " row %ld (+%lld)", i, d - 1);
        if (d > 0)
            gaps += (long)(d - 1), last = ids[i];
        else if (d < 0 && gaps > 0)
            gaps--;
    }
    return gaps;
}

typedef struct cube_facts {
    long naxis3, rows, good, damaged, gaps, nidgaps, underruns;
    int idx_ok;            /* SUCCESS rows have CUBE_IDX 0..good-1, others -1 */
    GString *where;        /* the first gaps and damaged rows, for the report */
} cube_facts;

/* Every pixel read frame by frame (a truncated cube fails) and the FRAMES
 * table's columns. */
static int read_cube(const char *path, cube_facts *cf, char *err, size_t n)
{
    fitsfile *f = NULL;
    int st = 0, naxis = 0, any = 0, cid = 0, cst = 0, cix = 0;
    long ax[3] = {0, 0, 0};
    LONGLONG nid = -1, nund = -1;
    GString *where = cf->where;
    memset(cf, 0, sizeof *cf);
    cf->where = where;
    cf->naxis3 = cf->rows = cf->nidgaps = -1;
    fits_open_diskfile(&f, path, READONLY, &st);
    fits_get_img_dim(f, &naxis, &st);
    fits_get_img_size(f, 3, ax, &st);
    if (!st && naxis != 3) {
        snprintf(err, n, "%s: not a 3-D cube (NAXIS %d)", path, naxis);
        goto close_file;
    }
    float *buf = g_new(float, ax[0] * ax[1] > 0 ? ax[0] * ax[1] : 1);
    for (long k = 0; !st && k < ax[2]; k++) {
        long fp[3] = {1, 1, k + 1};
        fits_read_pix(f, TFLOAT, fp, ax[0] * ax[1], NULL, buf, &any, &st);
    }
    g_free(buf);
    cf->naxis3 = ax[2];
    fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &st);
    fits_get_num_rows(f, &cf->rows, &st);
    fits_read_key(f, TLONGLONG, "NIDGAPS", &nid, NULL, &st);
    fits_read_key(f, TLONGLONG, "NUNDERRN", &nund, NULL, &st);
    fits_get_colnum(f, CASEINSEN, "FRAME_ID", &cid, &st);
    fits_get_colnum(f, CASEINSEN, "STATUS", &cst, &st);
    fits_get_colnum(f, CASEINSEN, "CUBE_IDX", &cix, &st);
    long rows = !st && cf->rows > 0 ? cf->rows : 0;
    LONGLONG *ids = g_new0(LONGLONG, rows + 1);
    int *idx = g_new0(int, rows + 1);
    char **names = g_new0(char *, rows + 1);
    char *text = g_new0(char, (rows + 1) * 17);
    for (long i = 0; i < rows; i++)
        names[i] = text + i * 17;
    fits_read_col(f, TLONGLONG, cid, 1, 1, rows, NULL, ids, &any, &st);
    fits_read_col(f, TSTRING, cst, 1, 1, rows, NULL, names, &any, &st);
    fits_read_col(f, TINT, cix, 1, 1, rows, NULL, idx, &any, &st);
    cf->idx_ok = 1;
    for (long i = 0; !st && i < rows; i++) {
        if (!strcmp(names[i], "SUCCESS")) {
            cf->idx_ok &= idx[i] == cf->good;
            cf->good++;
        } else {
            cf->idx_ok &= idx[i] == -1;
            if (cf->damaged++ < 6)
                g_string_append_printf(cf->where, " row %ld id %lld %s", i, (long long)ids[i],
                                       names[i]);
        }
    }
    if (cf->damaged)
        g_string_append(cf->where, ";");
    cf->gaps = id_gaps(ids, rows, cf->where);
    cf->nidgaps = (long)nid;
    cf->underruns = (long)nund;
    g_free(text);
    g_free(names);
    g_free(idx);
    g_free(ids);
close_file:
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    if (st) {
        char t[FLEN_STATUS] = "";
        fits_get_errstatus(st, t);
        snprintf(err, n, "%s: cfitsio: %s", path, t);
    }
    return st || naxis != 3 ? -1 : 0;
}

typedef struct recon_files {
    GHashTable *files;     /* path -> NULL: what the catalogue names */
    int rows;
} recon_files;

static int on_recon(const catalog_recon *r, void *user)
{
    recon_files *rf = user;
    rf->rows++;
    if (r->output_fits)
        g_hash_table_add(rf->files, g_strdup(r->output_fits));
    if (r->output_png)
        g_hash_table_add(rf->files, g_strdup(r->output_png));
    return 0;
}

/* One run: catalogue row against the cube on disk and its FRAMES table. */
static void check_run(soak *s, catalog *cat, const soak_run *r, int k, GHashTable *expected)
{
    catalog_run cr;
    char want[512], hex[65], err[600];
    if (catalog_run_get(cat, r->uuid, &cr) != SL_OK) {
        soak_problem(s, "run %d %s: not in the catalogue: %s", k, r->uuid, catalog_errmsg(cat));
        return;
    }
    s->f.requested += r->frames;
    s->f.catalogued += cr.frames_acquired;
    snprintf(want, sizeof want, "%s/runs/%s.fits", s->b.data, r->uuid);
    if (cr.state != CATALOG_DONE || cr.exit_reason)
        soak_problem(s, "run %d %.8s: catalogue state %s (%s)", k, r->uuid,
                     catalog_state_name(cr.state), cr.exit_reason ? cr.exit_reason : "-");
    if (cr.frames_requested != r->frames || cr.frames_acquired != r->frames)
        soak_problem(s, "run %d %.8s: catalogue says %d of %d frames, %d requested", k, r->uuid,
                     cr.frames_acquired, cr.frames_requested, r->frames);
    if (!cr.file_path || strcmp(cr.file_path, want)) {
        soak_problem(s, "run %d %.8s: catalogued file %s, expected %s", k, r->uuid,
                     cr.file_path ? cr.file_path : "(none)", want);
    } else if (sha256_file(want, hex) != 0) {
        soak_problem(s, "run %d %.8s: cannot read %s", k, r->uuid, want);
    } else if (!cr.file_sha256 || strcmp(cr.file_sha256, hex)) {
        soak_problem(s, "run %d %.8s: sha256 %s catalogued, %s on disk", k, r->uuid,
                     cr.file_sha256 ? cr.file_sha256 : "(none)", hex);
    }
    cube_facts cf = {.where = g_string_new(NULL)};
    if (read_cube(want, &cf, err, sizeof err) != 0) {
        soak_problem(s, "run %d %.8s: %s", k, r->uuid, err);
    } else {
        s->f.naxis3 += cf.naxis3;
        s->f.damaged += cf.damaged;
        s->f.gaps += cf.gaps;
        if (cf.good > cf.naxis3)
            s->f.lost += cf.good - cf.naxis3;
        if (cf.naxis3 != r->frames || cf.good != cf.naxis3 || !cf.idx_ok)
            soak_problem(s, "run %d %.8s: NAXIS3 %ld, %ld SUCCESS rows (CUBE_IDX %s), %d "
                         "requested", k, r->uuid, cf.naxis3, cf.good,
                         cf.idx_ok ? "in order" : "NOT 0..N-1", r->frames);
        if (cf.damaged != cr.frames_failed)
            soak_problem(s, "run %d %.8s: %ld damaged rows, catalogue frames_failed %d", k,
                         r->uuid, cf.damaged, cr.frames_failed);
        if (cf.gaps != cf.nidgaps) {
            s->f.gaps_unaccounted++;
            soak_problem(s, "run %d %.8s: %ld frame-id gaps in FRAMES, NIDGAPS %ld", k, r->uuid,
                         cf.gaps, cf.nidgaps);
        }
        if (cf.damaged || cf.gaps)   /* accounted for, but worth seeing */
            printf("soak: run %d %.8s: %ld damaged, %ld id gaps (%ld buffer underruns):%s\n", k,
                   r->uuid, cf.damaged, cf.gaps, cf.underruns, cf.where->str);
    }
    g_string_free(cf.where, TRUE);
    recon_files rf = {expected, 0};
    if (catalog_recon_list(cat, r->uuid, on_recon, &rf) != SL_OK)
        soak_problem(s, "run %d %.8s: reconstructions: %s", k, r->uuid, catalog_errmsg(cat));
    else if (rf.rows != r->reconstructs)
        soak_problem(s, "run %d %.8s: %d reconstruction rows, expected %d", k, r->uuid, rf.rows,
                     r->reconstructs);
    s->disk.recon_rows += rf.rows;
    catalog_run_clear(&cr);
}

typedef struct run_rows {
    GHashTable *files;
    int rows;
} run_rows;

static int on_run(const catalog_run *r, void *user)
{
    run_rows *rr = user;
    rr->rows++;
    if (r->file_path)
        g_hash_table_add(rr->files, g_strdup(r->file_path));
    return 0;
}

/* Each file in DATA/sub is in expected, and each of expected's paths under
 * DATA/sub exists. */
static void match_dir(soak *s, const char *sub, GHashTable *expected)
{
    char *dir = g_build_filename(s->b.data, sub, NULL);
    DIR *d = opendir(dir);
    GHashTable *seen = g_hash_table_new_full(g_str_hash, g_str_equal, g_free, NULL);
    for (struct dirent *e; d && (e = readdir(d));) {
        if (e->d_name[0] == '.')
            continue;
        char *p = g_build_filename(dir, e->d_name, NULL);
        s->disk.files++;
        if (!g_hash_table_contains(expected, p)) {
            s->disk.mismatches++;
            soak_problem(s, "%s has no catalogue row", p);
        }
        g_hash_table_add(seen, p);
    }
    if (d)
        closedir(d);
    GHashTableIter it;
    gpointer key;
    g_hash_table_iter_init(&it, expected);
    while (g_hash_table_iter_next(&it, &key, NULL))
        if (g_str_has_prefix(key, dir) && !g_hash_table_contains(seen, key)) {
            s->disk.mismatches++;
            soak_problem(s, "catalogued %s is not on disk", (const char *)key);
        }
    g_hash_table_destroy(seen);
    g_free(dir);
}

void soak_check_files(soak *s)
{
    char path[300];
    catalog *cat = NULL;
    sl_err e = {0};
    snprintf(path, sizeof path, "%s/specklab.db", s->b.data);
    if (catalog_open(&cat, path, &e) != SL_OK) {
        soak_problem(s, "catalog_open %s: %s", path, e.msg);
        return;
    }
    if (catalog_integrity_check(cat) != SL_OK)
        soak_problem(s, "catalogue integrity: %s", catalog_errmsg(cat));
    GHashTable *recons = g_hash_table_new_full(g_str_hash, g_str_equal, g_free, NULL);
    for (int k = 0; k < s->nruns; k++)
        check_run(s, cat, &s->runs[k], k, recons);
    run_rows rr = {g_hash_table_new_full(g_str_hash, g_str_equal, g_free, NULL), 0};
    if (catalog_run_list(cat, NULL, on_run, &rr) != SL_OK)
        soak_problem(s, "listing runs: %s", catalog_errmsg(cat));
    s->disk.run_rows = rr.rows;
    if (rr.rows != s->nruns) {
        s->disk.mismatches++;
        soak_problem(s, "%d runs in the catalogue, %d submitted", rr.rows, s->nruns);
    }
    match_dir(s, "runs", rr.files);
    match_dir(s, "recon", recons);
    g_hash_table_destroy(rr.files);
    g_hash_table_destroy(recons);
    catalog_close(cat);
}
