/* cliutil.c - helpers shared by the subcommands (see cli.h). */
#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <time.h>

gboolean cli_parse_size(const char *text, int *w, int *h, GError **error)
{
    char *end = NULL;
    long a = strtol(text, &end, 10), b = a;
    if (end != text && (*end == 'x' || *end == 'X')) {
        const char *rest = end + 1;
        b = strtol(rest, &end, 10);
        if (end == rest)
            b = -1;
    }
    if (end == text || *end != '\0' || a < 8 || b < 8 || a > 8192 || b > 8192) {
        g_set_error(error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE,
                    "--size '%s': expected N or WxH with 8 <= N <= 8192", text);
        return FALSE;
    }
    *w = (int)a;
    *h = (int)b;
    return TRUE;
}

gboolean cli_parse(GOptionContext *ctx, int *argc, char ***argv)
{
    GError *error = NULL;
    if (!g_option_context_parse(ctx, argc, argv, &error)) {
        fprintf(stderr, "%s: %s (try --help)\n", (*argv)[0], error->message);
        g_error_free(error);
        return FALSE;
    }
    return TRUE;
}

void cli_print_json(JsonBuilder *b)
{
    JsonNode *root = json_builder_get_root(b);
    JsonGenerator *g = json_generator_new();
    json_generator_set_root(g, root);
    gchar *text = json_generator_to_data(g, NULL);
    printf("%s\n", text);
    g_free(text);
    g_object_unref(g);
    json_node_unref(root);
}

void cli_json_str(JsonBuilder *b, const char *k, const char *v)
{
    json_builder_set_member_name(b, k);
    json_builder_add_string_value(b, v);
}

void cli_json_int(JsonBuilder *b, const char *k, gint64 v)
{
    json_builder_set_member_name(b, k);
    json_builder_add_int_value(b, v);
}

void cli_json_num(JsonBuilder *b, const char *k, double v)
{
    json_builder_set_member_name(b, k);
    if (isfinite(v))
        json_builder_add_double_value(b, v);
    else
        json_builder_add_null_value(b);
}

double cli_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

double cli_peak_rss_mb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss / 1024.0; /* Linux reports kB */
}
