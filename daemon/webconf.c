/* webconf.c - the web page's listen address; see webconf.h. */
#include "webconf.h"

#include <arpa/inet.h>
#include <glib.h>
#include <stdlib.h>
#include <string.h>

/* 127.0.0.0/8 or ::1 (also ::ffff:127.x.y.z). */
static int is_loopback(const char *host, int v6)
{
    unsigned char a[16];
    if (!v6)
        return inet_pton(AF_INET, host, a) == 1 && a[0] == 127;
    if (inet_pton(AF_INET6, host, a) != 1)
        return 0;
    static const unsigned char one[16] = {[15] = 1};
    static const unsigned char mapped[12] = {[10] = 0xff, [11] = 0xff};
    return !memcmp(a, one, 16) || (!memcmp(a, mapped, 12) && a[12] == 127);
}

int webconf_parse(const char *text, char **host, int *port, int *loopback, sl_err *err)
{
    const char *colon = text ? strrchr(text, ':') : NULL;
    *host = NULL;
    if (!colon || colon == text)
        return sl_seterr(err, SL_EINVAL, "'%s': expected HOST:PORT (127.0.0.1:8080)",
                         text ? text : "");
    char *end = NULL;
    long p = strtol(colon + 1, &end, 10);
    if (end == colon + 1 || *end || p < 0 || p > 65535)
        return sl_seterr(err, SL_EINVAL, "'%s': the port must be 0..65535", text);
    char *h = g_strndup(text, (size_t)(colon - text));
    int v6 = 0;
    unsigned char a[16];
    size_t n = strlen(h);
    if (n >= 2 && h[0] == '[' && h[n - 1] == ']') {
        memmove(h, h + 1, n - 2);
        h[n - 2] = '\0';
        v6 = 1;
    }
    if (!v6 && !strcmp(h, "localhost")) {
        g_free(h);
        h = g_strdup("127.0.0.1");
    }
    int ok = v6 ? inet_pton(AF_INET6, h, a) == 1 : inet_pton(AF_INET, h, a) == 1;
    if (!ok) {
        sl_seterr(err, SL_EINVAL, "'%s': the host must be an IPv4 address, [IPv6] or "
                  "localhost (names are not resolved)", text);
        g_free(h);
        return SL_EINVAL;
    }
    *host = h;
    *port = (int)p;
    *loopback = is_loopback(h, v6);
    return SL_OK;
}

int webconf_set(config *c, const char *what, const char *text, int allow_remote,
                const char *allow_name, sl_err *err)
{
    char *host = NULL;
    int port = 0, loopback = 0;
    g_free(c->web_host);
    c->web_host = NULL;
    c->web_port = 0;
    c->web_loopback = 1;
    c->web_allow_remote = allow_remote;
    if (!text || !*text)
        return SL_OK;
    sl_err e = {0};
    if (webconf_parse(text, &host, &port, &loopback, &e) != SL_OK)
        return sl_seterr(err, SL_EINVAL, "%s = %s", what, e.msg);
    if (!loopback && !allow_remote) {
        sl_seterr(err, SL_EINVAL, "%s = '%s': not a loopback address; the page has no "
                  "authentication, so serving it beyond this host needs %s", what, text,
                  allow_name);
        g_free(host);
        return SL_EINVAL;
    }
    c->web_host = host;
    c->web_port = port;
    c->web_loopback = loopback;
    if (c->web_max_connections <= 0)
        c->web_max_connections = 32;
    return SL_OK;
}
