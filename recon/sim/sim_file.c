/* sim_file.c - see sim_file.h. */
#include "sim_file.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int sim_file_add_truth(sim *s, cube_writer *w, float *buf, sl_err *err)
{
    const sim_opts *o = sim_options(s);
    int rc;
    if ((rc = sim_truth(s, buf)) != SL_OK)
        return sl_seterr(err, rc, "truth: %s", sim_errmsg(s));
    if ((rc = cube_writer_add_image(w, "TRUTH", buf, o->width, o->height,
                                    NULL)) != SL_OK)
        return sl_seterr(err, rc, "%s", cube_writer_errmsg(w));
    if ((rc = sim_cophased(s, buf)) != SL_OK)
        return sl_seterr(err, rc, "cophased image: %s", sim_errmsg(s));
    if ((rc = cube_writer_add_image(w, "COPHASED", buf, o->width, o->height,
                                    NULL)) != SL_OK)
        return sl_seterr(err, rc, "%s", cube_writer_errmsg(w));
    return SL_OK;
}

int sim_file_write_sidecar(sim *s, const char *path, const cube_meta *md,
                           float *buf, sl_err *err)
{
    const sim_opts *o = sim_options(s);
    cube_writer *w = NULL;
    int rc = cube_writer_open(&w, path, o->width, o->height, -32, md, err);
    if (rc != SL_OK)
        return rc;
    if ((rc = sim_truth(s, buf)) != SL_OK)
        sl_seterr(err, rc, "truth: %s", sim_errmsg(s));
    else if ((rc = cube_writer_append(w, buf)) != SL_OK)
        sl_seterr(err, rc, "%s", cube_writer_errmsg(w));
    if (rc == SL_OK)
        rc = sim_file_add_truth(s, w, buf, err);
    if (rc == SL_OK && (rc = cube_writer_close(w)) != SL_OK)
        sl_seterr(err, rc, "%s", cube_writer_errmsg(w));
    cube_writer_free(w);
    return rc;
}

char *sim_file_sidecar_path(const char *cube_path)
{
    size_t n = strlen(cube_path);
    int ext = n > 5 && strcmp(cube_path + n - 5, ".fits") == 0;
    size_t stem = ext ? n - 5 : n;
    char *p = malloc(stem + sizeof "-truth.fits");
    if (p)
        snprintf(p, stem + sizeof "-truth.fits", "%.*s-truth.fits",
                 (int)stem, cube_path);
    return p;
}
