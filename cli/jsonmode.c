/* jsonmode.c - see jsonmode.h. */
#include "jsonmode.h"

#include <json-glib/json-glib.h>
#include <string.h>
#include <unistd.h>

int jsonmode_wanted(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--"))
            return 0;
        if (!strcmp(argv[i], "--json"))
            return 1;
    }
    return 0;
}

/* Point fd at a fresh temporary file; the FILE reads it back later. */
static FILE *capture(int fd, int *saved)
{
    FILE *f = tmpfile();
    if (!f)
        return NULL;
    *saved = dup(fd);
    if (*saved < 0 || dup2(fileno(f), fd) < 0) {
        if (*saved >= 0)
            close(*saved);
        fclose(f);
        return NULL;
    }
    return f;
}

static void restore(int fd, int saved)
{
    dup2(saved, fd);
    close(saved);
}

void jsonmode_begin(jsonmode *jm)
{
    memset(jm, 0, sizeof *jm);
    fflush(stdout);
    fflush(stderr);
    if (!(jm->out = capture(STDOUT_FILENO, &jm->saved_out)))
        goto fail;
    if (!(jm->err = capture(STDERR_FILENO, &jm->saved_err))) {
        restore(STDOUT_FILENO, jm->saved_out);
        fclose(jm->out);
        goto fail;
    }
    jm->active = 1;
    return;
fail:
    fprintf(stderr, "specklab: warning: cannot capture output for --json "
                    "errors; errors stay plain text\n");
}

/* The whole of a capture file, NUL-terminated (g_free it). */
static char *slurp(FILE *f)
{
    GString *s = g_string_new(NULL);
    char buf[4096];
    size_t n;
    rewind(f);
    while ((n = fread(buf, 1, sizeof buf, f)) > 0)
        g_string_append_len(s, buf, (gssize)n);
    fclose(f);
    return g_string_free(s, FALSE);
}

/* One stderr line without the "specklab CMD: " prefix and "(try
 * --help)" hint, which mean nothing to a program. */
static char *clean_line(const char *line)
{
    const char *p = line;
    if (!strncmp(p, "specklab", 8)) {
        const char *colon = strstr(p, ": ");
        if (colon)
            p = colon + 2;
    }
    char *s = g_strdup(p);
    char *hint = strstr(s, " (try --help)");
    if (hint)
        *hint = 0;
    return g_strstrip(s);
}

static JsonNode *error_node(const char *command, int status, const char *err)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "command");
    json_builder_add_string_value(b, command);
    json_builder_set_member_name(b, "status");
    json_builder_add_int_value(b, status);
    json_builder_set_member_name(b, "kind");
    json_builder_add_string_value(b, status == 2 ? "usage" : "failure");
    char **lines = g_strsplit(err, "\n", -1);
    char *last = NULL;
    json_builder_set_member_name(b, "messages");
    json_builder_begin_array(b);
    for (char **l = lines; *l; l++) {
        char *c = clean_line(*l);
        if (*c) {
            json_builder_add_string_value(b, c);
            g_free(last);
            last = g_strdup(c);
        }
        g_free(c);
    }
    json_builder_end_array(b);
    json_builder_set_member_name(b, "message");
    json_builder_add_string_value(b, last ? last : "failed without a message");
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    g_free(last);
    g_strfreev(lines);
    return n;
}

/* The failed command's stdout with the error added: its own object when
 * it printed one, else a new one (any other text is kept before it). */
static void print_failure(const char *out, JsonNode *error)
{
    JsonParser *p = json_parser_new();
    JsonNode *root = NULL;
    if (*out && json_parser_load_from_data(p, out, -1, NULL)) {
        JsonNode *r = json_parser_get_root(p);
        if (r && JSON_NODE_HOLDS_OBJECT(r))
            root = json_node_copy(r);
    }
    if (!root) {
        fputs(out, stdout);
        root = json_node_init_object(json_node_alloc(), json_object_new());
    }
    json_object_set_member(json_node_get_object(root), "error", error);
    char *text = json_to_string(root, FALSE);
    printf("%s\n", text);
    g_free(text);
    json_node_unref(root);
    g_object_unref(p);
}

int jsonmode_end(jsonmode *jm, const char *command, int status)
{
    if (!jm->active)
        return status;
    fflush(stdout);
    fflush(stderr);
    restore(STDOUT_FILENO, jm->saved_out);
    restore(STDERR_FILENO, jm->saved_err);
    char *out = slurp(jm->out), *err = slurp(jm->err);
    fputs(err, stderr);
    if (status == 0)
        fputs(out, stdout);
    else
        print_failure(out, error_node(command, status, err));
    fflush(stdout);
    g_free(out);
    g_free(err);
    jm->active = 0;
    return status;
}
