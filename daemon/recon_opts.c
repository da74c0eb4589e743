/* recon_opts.c - see recon_opts.h. */
#include "recon_opts.h"

#include <stdio.h>
#include <string.h>

/* A member's value as the text recon's command line would carry. */
static char *value_text(JsonNode *n)
{
    if (!n || !JSON_NODE_HOLDS_VALUE(n))
        return NULL;
    GType t = json_node_get_value_type(n);
    if (t == G_TYPE_STRING)
        return g_strdup(json_node_get_string(n));
    if (t == G_TYPE_BOOLEAN)
        return g_strdup(json_node_get_boolean(n) ? "true" : "false");
    if (t == G_TYPE_INT64)
        return g_strdup_printf("%" G_GINT64_FORMAT, json_node_get_int(n));
    if (t == G_TYPE_DOUBLE) {
        char buf[G_ASCII_DTOSTR_BUF_SIZE];
        return g_strdup(g_ascii_dtostr(buf, sizeof buf, json_node_get_double(n)));
    }
    return NULL;
}

/* The options as text into o (owned members), checked one by one. */
static char *read_members(JsonObject *opts, JsonObject *o, pipeline_opts *po)
{
    GList *keys = json_object_get_members(opts);
    char *why = NULL;
    for (GList *k = keys; k && !why; k = k->next) {
        const char *name = k->data;
        char *v = value_text(json_object_get_member(opts, name));
        sl_err e = {0};
        if (!v)
            why = g_strdup_printf("options: --%s must be a string, a number or a boolean",
                                  name);
        else if (pipeline_opts_set(po, name, v, &e) != SL_OK)
            why = g_strdup(e.msg);
        else
            json_object_set_string_member(o, name, v);
        g_free(v);
    }
    g_list_free(keys);
    return why;
}

char *recon_opts_read(JsonObject *args, char json_out[RECON_OPTS_MAX], char method_out[16],
                      int *projections)
{
    json_out[0] = '\0';
    JsonNode *n = json_object_get_member(args, "options");
    if (!n || JSON_NODE_HOLDS_NULL(n))
        return NULL;
    if (!JSON_NODE_HOLDS_OBJECT(n))
        return g_strdup("options must be an object of recon's options");
    pipeline_opts po;
    pipeline_opts_defaults(&po);
    JsonObject *o = json_object_new();
    char *why = read_members(json_node_get_object(n), o, &po);
    sl_err e = {0};
    if (!why && pipeline_opts_check(&po, &e) != SL_OK)
        why = g_strdup(e.msg);
    if (!why) {
        JsonNode *root = json_node_init_object(json_node_alloc(), o);
        char *text = json_to_string(root, FALSE);
        if (strlen(text) >= RECON_OPTS_MAX)
            why = g_strdup_printf("options: %zu bytes, at most %d", strlen(text),
                                  RECON_OPTS_MAX - 1);
        else
            snprintf(json_out, RECON_OPTS_MAX, "%s", text);
        g_free(text);
        json_node_unref(root);
        if (!why && json_object_has_member(o, "method"))
            snprintf(method_out, 16, "%s", pipeline_method_name(po.method));
        if (!why && json_object_has_member(o, "projections"))
            *projections = po.nangles;
    }
    json_object_unref(o);
    return why;
}

int recon_opts_apply(const char *json, pipeline_opts *po, sl_err *err)
{
    if (!json || !*json)
        return SL_OK;
    JsonNode *root = json_from_string(json, NULL);
    if (!root || !JSON_NODE_HOLDS_OBJECT(root)) {
        if (root)
            json_node_unref(root);
        return sl_seterr(err, SL_EINVAL, "options: not a JSON object");
    }
    JsonObject *o = json_node_get_object(root);
    GList *keys = json_object_get_members(o);
    int rc = SL_OK;
    for (GList *k = keys; k && rc == SL_OK; k = k->next)
        rc = pipeline_opts_set(po, k->data, json_object_get_string_member(o, k->data), err);
    g_list_free(keys);
    json_node_unref(root);
    return rc;
}

void recon_opts_params(const char *json, JsonBuilder *b)
{
    JsonNode *root = json && *json ? json_from_string(json, NULL) : NULL;
    if (!root)
        return;
    json_builder_set_member_name(b, "options");
    json_builder_add_value(b, root);   /* takes it */
}
