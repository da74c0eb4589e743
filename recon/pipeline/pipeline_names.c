/* pipeline_names.c - the names of the pipeline's methods (enum
 * pipeline_method) and skips (PIPE_SKIP_*): parse and print them.  Apart
 * from the estimators so that a configuration reader (specklabd's) can
 * check a method or a skips list without linking them. */
#include <stdio.h>
#include <string.h>

#include "pipeline.h"

/* in enum pipeline_method's order */
static const char *const method_names[] = {"direct", "tsm", "tsm-fourier", "auto"};
#define NMETHODS ((int)(sizeof method_names / sizeof method_names[0]))

int pipeline_method_parse(const char *name, int *method)
{
    for (int i = 0; name && i < NMETHODS; i++)
        if (strcmp(name, method_names[i]) == 0) {
            *method = i;
            return SL_OK;
        }
    return SL_EINVAL;
}

const char *pipeline_method_name(int method)
{
    return method >= 0 && method < NMETHODS ? method_names[method] : "unknown";
}

static const struct {
    const char *name;
    int bit;
} skip_names[] = {{"reject", PIPE_SKIP_REJECT}, {"crop", PIPE_SKIP_CROP},
                  {"support", PIPE_SKIP_SUPPORT}, {"angles", PIPE_SKIP_ANGLES}};

int pipeline_skips_parse(const char *list, int *skips)
{
    *skips = 0;
    if (!strcmp(list, "none"))
        return SL_OK;
    if (!strcmp(list, "all")) {
        *skips = PIPE_SKIP_ALL;
        return SL_OK;
    }
    const char *p = list;
    while (*p) {
        size_t len = strcspn(p, ",");
        int found = 0;
        for (size_t i = 0; i < sizeof skip_names / sizeof skip_names[0]; i++)
            if (len == strlen(skip_names[i].name) &&
                !strncmp(p, skip_names[i].name, len)) {
                *skips |= skip_names[i].bit;
                found = 1;
            }
        if (!found)
            return SL_EINVAL;
        p += len + (p[len] == ',');
    }
    return SL_OK;
}

void pipeline_skips_name(int skips, char *buf, int n)
{
    int used = 0;
    buf[0] = 0;
    for (size_t i = 0; i < sizeof skip_names / sizeof skip_names[0]; i++)
        if ((skips & skip_names[i].bit) && used < n)
            used += snprintf(buf + used, (size_t)(n - used), "%s%s",
                             used ? "," : "", skip_names[i].name);
    if (!used)
        snprintf(buf, (size_t)n, "none");
}
