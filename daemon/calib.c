/* calib.c - see calib.h. */
#include "calib.h"

#include <glib.h>
#include <stdio.h>
#include <string.h>

#include "cubefile.h"
#include "proto.h"

static const char *const names[CALIB_N] = {"dark", "flat", "flat_dark", "badpix", "ref"};

/* The cube of the `kind` run matched to run `uuid`, into slot k.  A match
 * whose cube is gone or lies outside the data directory is skipped with a
 * warning: calibration is optional, a missing one must not fail the run. */
static int from_catalogue(catalog *cat, const config *cfg, const char *uuid,
                          catalog_kind kind, calib_set *c, int k, sl_err *err)
{
    char found[CATALOG_UUID_LEN + 1];
    int rc = catalog_run_find_calibration(cat, uuid, kind, found);
    if (rc == SL_EEND)
        return SL_OK;
    if (rc != SL_OK)
        return sl_seterr(err, rc, "%s", catalog_errmsg(cat));
    catalog_run r;
    if ((rc = catalog_run_get(cat, found, &r)) != SL_OK)
        return sl_seterr(err, rc, "%s", catalog_errmsg(cat));
    if (r.file_path && cubefile_under(cfg->data_dir, r.file_path) &&
        g_file_test(r.file_path, G_FILE_TEST_IS_REGULAR)) {
        c->path[k] = g_strdup(r.file_path);
        snprintf(c->run[k], sizeof c->run[k], "%s", found);
    } else {
        g_warning("run %s: the %s run %s has no cube under %s; not used", uuid,
                  catalog_kind_name(kind), found, cfg->data_dir);
    }
    catalog_run_clear(&r);
    return SL_OK;
}

/* The reference named by the request: a done calibrator run's cube. */
static int named_ref(catalog *cat, const config *cfg, const char *ref, calib_set *c,
                     sl_err *err)
{
    char id[CATALOG_UUID_LEN + 1];
    catalog_run r;
    if (catalog_run_resolve(cat, ref, id) != SL_OK || catalog_run_get(cat, id, &r) != SL_OK)
        return sl_seterr(err, SL_EINVAL, "calibrator %s: %s", ref, catalog_errmsg(cat));
    int ok = r.kind == CATALOG_CALIBRATOR && r.state == CATALOG_DONE && r.file_path &&
             cubefile_under(cfg->data_dir, r.file_path);
    if (ok) {
        c->path[CALIB_REF] = g_strdup(r.file_path);
        snprintf(c->run[CALIB_REF], sizeof c->run[CALIB_REF], "%s", id);
    } else {
        sl_seterr(err, SL_EINVAL, "calibrator %s is a %s run, %s%s: a reference is a done "
                  "calibrator run with its cube", id, catalog_kind_name(r.kind),
                  catalog_state_name(r.state), r.file_path ? "" : ", no cube");
    }
    catalog_run_clear(&r);
    return ok ? SL_OK : SL_EINVAL;
}

static int find_ref(catalog *cat, const config *cfg, const char *uuid, catalog_kind kind,
                    const char *ref, calib_set *c, sl_err *err)
{
    if (ref && !strcmp(ref, "none"))
        return SL_OK;
    if (ref)
        return named_ref(cat, cfg, ref, c, err);
    /* a calibrator is not calibrated by another; darks and flats are
     * never reconstructed */
    if (kind != CATALOG_SCIENCE || !cfg->calib_catalogued)
        return SL_OK;
    return from_catalogue(cat, cfg, uuid, CATALOG_CALIBRATOR, c, CALIB_REF, err);
}

int calib_find(catalog *cat, const config *cfg, const char *uuid, catalog_kind kind,
               const char *ref, calib_set *out, sl_err *err)
{
    memset(out, 0, sizeof *out);
    const char *file[CALIB_N] = {cfg->calib_dark, cfg->calib_flat, cfg->calib_flat_dark,
                                 cfg->calib_badpix, NULL};
    for (int k = 0; k < CALIB_N; k++)
        out->path[k] = g_strdup(file[k]);
    int rc = find_ref(cat, cfg, uuid, kind, ref, out, err);
    if (rc != SL_OK || !cfg->calib_catalogued) {
        if (rc != SL_OK)
            calib_clear(out);
        return rc;
    }
    if (!out->path[CALIB_DARK])
        rc = from_catalogue(cat, cfg, uuid, CATALOG_DARK, out, CALIB_DARK, err);
    /* a configured flat comes with its configured dark (or none) */
    if (rc == SL_OK && !out->path[CALIB_FLAT]) {
        rc = from_catalogue(cat, cfg, uuid, CATALOG_FLAT, out, CALIB_FLAT, err);
        if (rc == SL_OK && out->run[CALIB_FLAT][0])
            rc = from_catalogue(cat, cfg, out->run[CALIB_FLAT], CATALOG_DARK, out,
                                CALIB_FLAT_DARK, err);
    }
    if (rc != SL_OK)
        calib_clear(out);
    return rc;
}

void calib_apply(const calib_set *c, pipeline_opts *po)
{
    po->dark_path = c->path[CALIB_DARK];
    po->flat_path = c->path[CALIB_FLAT];
    po->flat_dark_path = c->path[CALIB_FLAT_DARK];
    po->badpix_path = c->path[CALIB_BADPIX];
    po->ref_path = c->path[CALIB_REF];
}

void calib_json(const calib_set *c, JsonBuilder *b)
{
    for (int k = 0; k < CALIB_N; k++) {
        if (!c->path[k])
            continue;
        json_builder_set_member_name(b, names[k]);
        json_builder_begin_object(b);
        proto_add_str(b, "file", c->path[k]);
        if (c->run[k][0])
            proto_add_str(b, "run", c->run[k]);
        json_builder_end_object(b);
    }
}

void calib_clear(calib_set *c)
{
    for (int k = 0; k < CALIB_N; k++)
        g_free(c->path[k]);
    memset(c, 0, sizeof *c);
}
