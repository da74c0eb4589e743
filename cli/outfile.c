/* outfile.c - see outfile.h. */
#include "outfile.h"

#include <errno.h>
#include <glob.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define OUTFILE_ERROR (g_quark_from_static_string("specklab-outfile"))

/* Is one of the files input names (a path or a glob) the file st? */
static const char *same_as(const struct stat *st, const char *input)
{
    glob_t g;
    const char *hit = NULL;
    if (strpbrk(input, "*?[") && glob(input, 0, NULL, &g) == 0) {
        for (size_t i = 0; !hit && i < g.gl_pathc; i++) {
            struct stat is;
            if (stat(g.gl_pathv[i], &is) == 0 && is.st_dev == st->st_dev &&
                is.st_ino == st->st_ino)
                hit = input;
        }
        globfree(&g);
        return hit;
    }
    struct stat is;
    if (stat(input, &is) == 0 && is.st_dev == st->st_dev && is.st_ino == st->st_ino)
        return input;
    return NULL;
}

gboolean outfile_check(const char *path, gboolean overwrite,
                       const char *const *inputs, int ninputs, GError **error)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return TRUE; /* nothing there: nothing to lose */
    for (int i = 0; i < ninputs; i++) {
        const char *hit = inputs[i] ? same_as(&st, inputs[i]) : NULL;
        if (hit) {
            g_set_error(error, OUTFILE_ERROR, 1, "refusing to write %s: it is "
                        "the input %s (even with --overwrite)", path, hit);
            return FALSE;
        }
    }
    if (S_ISDIR(st.st_mode)) {
        g_set_error(error, OUTFILE_ERROR, 2, "%s is a directory, not a file",
                    path);
        return FALSE;
    }
    if (!overwrite) {
        g_set_error(error, OUTFILE_ERROR, 3, "%s exists; give --overwrite to "
                    "replace it", path);
        return FALSE;
    }
    return TRUE;
}

gboolean outfile_begin(outfile *f, const char *path, gboolean overwrite,
                       const char *const *inputs, int ninputs, GError **error)
{
    memset(f, 0, sizeof *f);
    if (!outfile_check(path, overwrite, inputs, ninputs, error))
        return FALSE;
    char *dir = g_path_get_dirname(path), *base = g_path_get_basename(path);
    char *tmp = g_strdup_printf("%s/.%s.XXXXXX", dir, base);
    g_free(dir);
    g_free(base);
    /* mkstemp makes the name unique; the writer creates the file afresh
     * (with the usual permissions, not mkstemp's 0600). */
    int fd = g_mkstemp(tmp);
    if (fd < 0) {
        g_set_error(error, OUTFILE_ERROR, 4, "cannot write in the directory "
                    "of %s: %s", path, g_strerror(errno));
        g_free(tmp);
        return FALSE;
    }
    close(fd);
    unlink(tmp);
    f->path = g_strdup(path);
    f->tmp = tmp;
    return TRUE;
}

gboolean outfile_commit(outfile *f, GError **error)
{
    if (rename(f->tmp, f->path) != 0) {
        g_set_error(error, OUTFILE_ERROR, 5, "cannot rename %s to %s: %s",
                    f->tmp, f->path, g_strerror(errno));
        return FALSE;
    }
    g_free(f->tmp);
    f->tmp = NULL;
    return TRUE;
}

void outfile_clear(outfile *f)
{
    if (!f)
        return;
    if (f->tmp)
        unlink(f->tmp);
    g_free(f->tmp);
    g_free(f->path);
    memset(f, 0, sizeof *f);
}
