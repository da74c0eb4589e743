/* test_daemon_clients.c - the fault matrix's misbehaving clients, each on
 * its own simulated bench (daemon_fx.h):
 *   ids_out_of_range  ids (and any integer) of 2^63 or more, or below
 *                     -2^63, get bad-request (json-glib would read 2^64-1
 *                     as -1); the extremes of the range are served.
 * Waits are on the daemon's own replies.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

/* ---- ids ---------------------------------------------------------------------- */

/* Send line, read the reply (kept). */
static JsonNode *raw_call(bench *b, dc *c, const char *line)
{
    if (dc_send_raw(c, line, strlen(line)) != 0)
        return NULL;
    return keep(b, dc_wait_reply(c, -1, 5));
}

BENCH_TEST(ids_out_of_range, 60, NULL, NULL)
{
    dc *c = bench_client(b);
    CHECK(c, "connect");
    static const char *const refused[] = {
        "{\"id\": 18446744073709551615, \"cmd\": \"status\"}\n",
        "{\"id\": 9223372036854775808, \"cmd\": \"status\"}\n",
        "{ \"id\" : 36893488147419103232, \"cmd\": \"status\"}\n",
        "{\"cmd\": \"status\", \"id\": -9223372036854775809}\n"};
    for (size_t i = 0; i < G_N_ELEMENTS(refused); i++) {
        JsonNode *r = raw_call(b, c, refused[i]);
        CHECK(r && !jok(r) && !g_strcmp0(js(r, "error.code"), "bad-request") &&
                  jnull(r, "id") && strstr(mx_str(js(r, "error.message")), "id must be"),
              "%s -> %s", refused[i], jtext(r));
    }
    /* Any integer: an argument out of range is refused, its id echoed. */
    JsonNode *r = raw_call(b, c, "{\"id\": 5, \"cmd\": \"runs\", \"args\": {\"limit\": "
                                 "18446744073709551617}}\n");
    CHECK(r && !jok(r) && ji(r, "id") == 5 && !g_strcmp0(js(r, "error.code"), "bad-request") &&
              strstr(mx_str(js(r, "error.message")), "18446744073709551617"),
          "limit 2^64+1: %s", jtext(r));
    /* The range's ends are ids like any other; digits in a string or a
     * float are not integers. */
    r = raw_call(b, c, "{\"id\": 9223372036854775807, \"cmd\": \"status\"}\n");
    CHECK(jok(r) && ji(r, "id") == G_MAXINT64, "id 2^63-1: %s", jtext(r));
    r = raw_call(b, c, "{\"id\": -9223372036854775808, \"cmd\": \"status\"}\n");
    CHECK(jok(r) && ji(r, "id") == G_MININT64, "id -2^63: %s", jtext(r));
    r = raw_call(b, c, "{\"id\": 6, \"cmd\": \"runs\", \"args\": {\"state\": "
                       "\"18446744073709551615\", \"limit\": 3}}\n");
    CHECK(r && ji(r, "id") == 6 && !strstr(mx_str(js(r, "error.message")), "-2^63"),
          "digits in a string: %s", jtext(r));
}

TC_MAIN(TC_CASE(ids_out_of_range))
