/* progress.c - the catalogue progress writer of a run (progress.h). */
#include "progress.h"

#include <string.h>

static gpointer progress_main(gpointer data)
{
    progress_writer *p = data;
    catalog *cat = NULL;
    sl_err e = {0};
    catalog_opts co = {p->busy_timeout_ms};
    if (catalog_open_opts(&cat, p->db_path, &co, &e) != SL_OK) {
        g_warning("run %s: no catalogue progress during acquisition: %s", p->uuid, e.msg);
        cat = NULL;
    }
    g_mutex_lock(&p->mu);
    for (;;) {
        while (!p->posted && !p->stop)
            g_cond_wait(&p->cv, &p->mu);
        if (p->stop)          /* finish() writes the final counts itself */
            break;
        int stored = p->stored, failed = p->failed;
        int64_t missing = p->missing;
        p->posted = 0;
        g_mutex_unlock(&p->mu);
        /* Once per run: on a full disk or a locked catalogue every
         * second's write fails alike. */
        if (cat && catalog_run_update_progress(cat, p->uuid, stored, failed, missing) != SL_OK &&
            !p->warned++)
            g_warning("run %s: %s (progress not recorded)", p->uuid, catalog_errmsg(cat));
        g_mutex_lock(&p->mu);
    }
    g_mutex_unlock(&p->mu);
    catalog_close(cat);
    return NULL;
}

void progress_start(progress_writer *p, const char *db_path, int busy_timeout_ms,
                           const char *uuid)
{
    memset(p, 0, sizeof *p);
    p->db_path = db_path;
    p->busy_timeout_ms = busy_timeout_ms;
    p->uuid = uuid;
    g_mutex_init(&p->mu);
    g_cond_init(&p->cv);
    GError *ge = NULL;
    p->th = g_thread_try_new("progress", progress_main, p, &ge);
    if (!p->th) {
        g_warning("run %s: progress thread: %s (writing progress inline)", uuid, ge->message);
        g_error_free(ge);
    }
}

void progress_post(progress_writer *p, catalog *cat, int stored, int failed,
                          int64_t missing)
{
    if (!p->th) {
        if (catalog_run_update_progress(cat, p->uuid, stored, failed, missing) != SL_OK)
            g_warning("run %s: %s", p->uuid, catalog_errmsg(cat));
        return;
    }
    g_mutex_lock(&p->mu);
    p->stored = stored, p->failed = failed, p->missing = missing, p->posted = 1;
    g_cond_signal(&p->cv);
    g_mutex_unlock(&p->mu);
}

void progress_stop(progress_writer *p)
{
    if (p->th) {
        g_mutex_lock(&p->mu);
        p->stop = 1;
        g_cond_signal(&p->cv);
        g_mutex_unlock(&p->mu);
        g_thread_join(p->th);
        p->th = NULL;
    }
    if (p->db_path) {
        g_mutex_clear(&p->mu);
        g_cond_clear(&p->cv);
        p->db_path = NULL;
    }
}
