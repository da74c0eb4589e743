/* test_readme.c - README.md is a short manual that tells the truth.
 *
 * README.md has at most 300 lines.  Every relative link in README.md and
 * in the docs/ Markdown files names a file that exists.  Every command in their code
 * (fenced blocks and inline code spans) that starts with `specklab`,
 * `bin/specklab`, `specklabd` or `make` is checked against the programs:
 * the subcommand exists (`bin/specklab SUB --help` succeeds), each of its
 * options, long and short, appears in that help (or in `SUB WORD --help`
 * for `camera grab`, `runs list`, ...), and make targets are rules of the
 * Makefile or mk/install.mk.  Placeholders in capitals (COMMAND, RUN-ID), `…`
 * and `<...>` are skipped.  The last case feeds the checker a file with
 * one mistake of each kind and expects each reported: the check can fail.
 *
 * Run from the repository root (tests/run, make test); otherwise the root
 * is found two levels above the binary (BUILD/tests/test_readme).
 * SL_README_VERBOSE=1 prints each command checked.
 */
#define _GNU_SOURCE
#include <glib.h>
#include <libgen.h>
#include <limits.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include "proc_fx.h"
#include "tcheck.h"

#define README_MAX_LINES 300

/* What a check found wrong: one line per problem. */
typedef struct finds {
    GString *msg;
    int n;
    GHashTable *help; /* "SUB WORD" -> help text, "" when it failed */
    char bin[PATH_MAX], daemon[PATH_MAX], root[PATH_MAX];
} finds;

static void found(finds *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void found(finds *f, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (f->n < 12) { /* enough to act on; the count says the rest */
        g_string_append(f->msg, "\n    ");
        g_string_append_vprintf(f->msg, fmt, ap);
    }
    va_end(ap);
    f->n++;
}

/* The repository root: the working directory when it holds README.md and
 * the Makefile, else two levels above this binary. */
static int find_root(char *out, size_t n)
{
    if (access("README.md", R_OK) == 0 && access("Makefile", R_OK) == 0)
        return getcwd(out, n) ? 0 : -1;
    char exe[PATH_MAX] = "";
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[len > 0 ? len : 0] = 0;
    snprintf(out, n, "%s", dirname(dirname(dirname(exe))));
    char *mk = g_build_filename(out, "Makefile", NULL);
    int ok = access(mk, R_OK) == 0;
    g_free(mk);
    return ok ? 0 : -1;
}

static void finds_init(finds *f)
{
    memset(f, 0, sizeof *f);
    f->msg = g_string_new(NULL);
    f->help = g_hash_table_new_full(g_str_hash, g_str_equal, g_free, g_free);
    if (find_root(f->root, sizeof f->root) != 0)
        f->root[0] = 0;
    else if (chdir(f->root) != 0)
        f->root[0] = 0;
    fx_bin(f->bin, sizeof f->bin, "specklab");
    fx_bin(f->daemon, sizeof f->daemon, "specklabd");
}

static void finds_free(finds *f)
{
    g_string_free(f->msg, TRUE);
    g_hash_table_destroy(f->help);
}

/* The help text of `PROG ARGS... --help` (cached), NULL when it fails. */
static const char *help_of(finds *f, const char *prog, const char *a1, const char *a2)
{
    char *key = g_strdup_printf("%s %s %s", prog, a1 ? a1 : "", a2 ? a2 : "");
    const char *cached = g_hash_table_lookup(f->help, key);
    if (cached) {
        g_free(key);
        return *cached ? cached : NULL;
    }
    const char *argv[5] = {prog};
    int n = 1;
    if (a1)
        argv[n++] = a1;
    if (a2)
        argv[n++] = a2;
    argv[n++] = "--help";
    argv[n] = NULL;
    char *out = NULL;
    int st = -1;
    if (!g_spawn_sync(NULL, (char **)argv, NULL, G_SPAWN_STDERR_TO_DEV_NULL, NULL, NULL,
                      &out, NULL, &st, NULL) ||
        !WIFEXITED(st) || WEXITSTATUS(st) != 0 || !out || !*out) {
        g_free(out);
        out = g_strdup("");
    }
    g_hash_table_insert(f->help, key, out);
    return *out ? out : NULL;
}

/* A placeholder, not a real word: COMMAND, RUN-ID, <time>, FILE..., … */
static int placeholder(const char *w)
{
    if (strchr(w, '<') || strstr(w, "\xe2\x80\xa6") || strstr(w, "..."))
        return 1;
    int upper = 0, lower = 0;
    for (const char *p = w; *p; p++) {
        upper += g_ascii_isupper(*p);
        lower += g_ascii_islower(*p);
    }
    return upper > 0 && lower == 0;
}

/* opt ("--name" or "-x") is listed in help as an option: preceded by a
 * blank, '[' or ',' and followed by '=', a blank, ',', ']' or the end. */
static int help_lists(const char *help, const char *opt)
{
    size_t n = strlen(opt);
    for (const char *p = strstr(help, opt); p; p = strstr(p + 1, opt)) {
        char b = p == help ? ' ' : p[-1], a = p[n];
        if ((b == ' ' || b == '\t' || b == '\n' || b == '[' || b == ',' || b == '(') &&
            (a == '=' || a == ' ' || a == '\t' || a == '\n' || a == ',' || a == ']' ||
             a == '[' || a == 0))
            return 1;
    }
    return 0;
}

/* Shell-like words of one command line: quotes kept together, `#` at the
 * start of a word ends the line, redirections dropped; &&, ||, ;, | and &
 * end a command.  Returns commands, each a NULL-terminated word vector. */
static GPtrArray *split_commands(const char *line)
{
    GPtrArray *cmds = g_ptr_array_new_with_free_func((GDestroyNotify)g_strfreev);
    GPtrArray *words = g_ptr_array_new();
    GString *w = NULL;
    char quote = 0;
    int skip_next = 0;
    for (const char *p = line;; p++) {
        int end_word = !*p || (!quote && (*p == ' ' || *p == '\t'));
        int op = !quote && *p && strchr("&|;", *p);
        if (!quote && !w && *p == '#')
            end_word = 1, p += strlen(p); /* a comment: the rest goes */
        if (end_word || op) {
            if (w) {
                char *s = g_string_free(w, FALSE);
                if (skip_next || s[0] == '>' || s[0] == '<' || !strncmp(s, "2>", 2)) {
                    skip_next = !strcmp(s, ">") || !strcmp(s, ">>") || !strcmp(s, "<") ||
                                !strcmp(s, "2>");
                    g_free(s);
                } else {
                    g_ptr_array_add(words, s);
                }
                w = NULL;
            }
            if (op || !*p) {
                g_ptr_array_add(words, NULL);
                gchar **v = (gchar **)g_ptr_array_free(words, FALSE);
                if (v[0])
                    g_ptr_array_add(cmds, v);
                else
                    g_strfreev(v);
                words = g_ptr_array_new();
                while (op && (p[1] == '&' || p[1] == '|'))
                    p++;
            }
            if (!*p)
                break;
            continue;
        }
        if (!w)
            w = g_string_new(NULL);
        if (quote && *p == quote)
            quote = 0;
        else if (!quote && (*p == '\'' || *p == '"'))
            quote = *p;
        else
            g_string_append_c(w, *p);
    }
    g_ptr_array_free(words, TRUE);
    return cmds;
}

/* make TARGET: a rule `TARGET:` or a .PHONY entry in Makefile or mk/. */
static int make_has_target(const char *target)
{
    const char *files[] = {"Makefile", "mk/install.mk", NULL};
    char *t = g_regex_escape_string(target, -1);
    char *pat = g_strdup_printf("^%s[ \\t]*:|^\\.PHONY:.*[ \\t]%s([ \\t]|$)", t, t);
    g_free(t);
    GRegex *re = g_regex_new(pat, G_REGEX_MULTILINE, 0, NULL);
    int found_it = 0;
    for (int i = 0; files[i] && re && !found_it; i++) {
        char *text = NULL;
        if (g_file_get_contents(files[i], &text, NULL, NULL))
            found_it = g_regex_match(re, text, 0, NULL);
        g_free(text);
    }
    if (re)
        g_regex_unref(re);
    g_free(pat);
    return found_it;
}

/* Check one command (words) from file `where`. */
static void check_command(finds *f, const char *where, char **v)
{
    int i = 0;
    while (v[i] && (strchr(v[i], '=') && v[i][0] != '-')) /* VAR=value */
        i++;
    if (v[i] && !strcmp(v[i], "sudo"))
        i++;
    if (!v[i])
        return;
    const char *prog = v[i], *base = strrchr(prog, '/') ? strrchr(prog, '/') + 1 : prog;
    char **a = v + i + 1;
    if (base != prog && !g_str_has_suffix(prog, "bin/specklab") &&
        !g_str_has_suffix(prog, "bin/specklabd"))
        return; /* a path such as /var/lib/specklab, not a program */
    if (getenv("SL_README_VERBOSE") && (!strcmp(base, "make") || !strcmp(base, "specklab") ||
                                        !strcmp(base, "specklabd"))) {
        char *all = g_strjoinv(" ", v + i);
        fprintf(stderr, "%s: %s\n", where, all);
        g_free(all);
    }
    if (!strcmp(base, "make")) {
        for (; *a; a++)
            if ((*a)[0] != '-' && !strchr(*a, '=') && !strchr(*a, '/') && !placeholder(*a) &&
                !make_has_target(*a))
                found(f, "%s: `make %s`: no such target", where, *a);
        return;
    }
    const char *help, *what;
    if (!strcmp(base, "specklabd")) {
        help = help_of(f, f->daemon, NULL, NULL);
        what = "specklabd";
        if (!help) {
            found(f, "%s: `%s --help` failed", where, f->daemon);
            return;
        }
    } else if (!strcmp(base, "specklab")) {
        if (!a[0] || placeholder(a[0]))
            return;
        if (a[0][0] == '-') { /* specklab --version */
            help = help_of(f, f->bin, NULL, NULL);
            if (!help || !help_lists(help, a[0]))
                found(f, "%s: `specklab %s`: not in `specklab --help`", where, a[0]);
            return;
        }
        help = help_of(f, f->bin, a[0], NULL);
        if (!help) {
            found(f, "%s: `specklab %s`: no such command", where, a[0]);
            return;
        }
        what = a[0];
        const char *more = a[1] && a[1][0] != '-' && !placeholder(a[1]) ?
                           help_of(f, f->bin, a[0], a[1]) : NULL;
        a++;
        if (more) { /* camera grab, runs list, ...: both helps count */
            char *both = g_strconcat(help, "\n", more, NULL);
            char *key = g_strdup_printf("+%s %s", what, a[0]);
            g_hash_table_replace(f->help, key, both);
            help = both;
        }
    } else {
        return;
    }
    for (; *a; a++) {
        const char *w = *a;
        if (w[0] != '-' || !w[1] || g_ascii_isdigit(w[1]) || w[1] == '.' || !strcmp(w, "--"))
            continue;
        char *opt = w[1] == '-' ? g_strndup(w, strcspn(w, "=")) : g_strndup(w, 2);
        if (!placeholder(opt + 1) && strcmp(opt, "--help") && !help_lists(help, opt))
            found(f, "%s: `%s %s`: option not in its --help", where, what, opt);
        g_free(opt);
    }
}

/* Strip inline code spans from a prose line into `spans`; returns the
 * line without them (g_free). */
static char *take_spans(const char *line, GPtrArray *spans)
{
    GString *rest = g_string_new(NULL);
    for (const char *p = line; *p;) {
        if (*p != '`') {
            g_string_append_c(rest, *p++);
            continue;
        }
        size_t run = strspn(p, "`");
        char *fence = g_strndup(p, run);
        const char *close = strstr(p + run, fence);
        g_free(fence);
        if (!close) { /* an unclosed tick: literal */
            g_string_append_len(rest, p, (gssize)run);
            p += run;
            continue;
        }
        g_ptr_array_add(spans, g_strstrip(g_strndup(p + run, (gsize)(close - p - run))));
        p = close + run;
    }
    return g_string_free(rest, FALSE);
}

/* The links and the code of a Markdown file: link targets into `links`,
 * code lines (fenced, continuation lines joined; inline spans) into `code`. */
static void md_parse(const char *text, GPtrArray *links, GPtrArray *code)
{
    gchar **lines = g_strsplit(text, "\n", -1);
    int fenced = 0;
    GString *cont = NULL;
    for (int i = 0; lines[i]; i++) {
        const char *l = lines[i];
        const char *t = l + strspn(l, " \t");
        if (!strncmp(t, "```", 3)) {
            fenced = !fenced;
            continue;
        }
        if (fenced) {
            if (!cont)
                cont = g_string_new(NULL);
            g_string_append(cont, t);
            if (cont->len && cont->str[cont->len - 1] == '\\') {
                g_string_truncate(cont, cont->len - 1);
                continue;
            }
            char *c = g_string_free(cont, FALSE);
            cont = NULL;
            g_ptr_array_add(code, g_strdup(c + (!strncmp(c, "$ ", 2) ? 2 : 0)));
            g_free(c);
            continue;
        }
        char *rest = take_spans(l, code);
        for (const char *p = strstr(rest, "]("); p; p = strstr(p + 2, "](")) {
            const char *s = p + 2, *e = strchr(s, ')');
            if (e)
                g_ptr_array_add(links, g_strndup(s, (gsize)(e - s)));
        }
        g_free(rest);
    }
    if (cont)
        g_string_free(cont, TRUE);
    g_strfreev(lines);
}

/* Check one Markdown file: its relative links and its commands. */
static void check_md(finds *f, const char *path)
{
    char *text = NULL;
    if (!g_file_get_contents(path, &text, NULL, NULL)) {
        found(f, "%s: cannot read", path);
        return;
    }
    GPtrArray *links = g_ptr_array_new_with_free_func(g_free);
    GPtrArray *code = g_ptr_array_new_with_free_func(g_free);
    md_parse(text, links, code);
    char *dir = g_path_get_dirname(path);
    for (guint i = 0; i < links->len; i++) {
        char *t = g_strstrip(g_strdup(links->pdata[i]));
        t[strcspn(t, " \t#")] = 0; /* drop a title and a fragment */
        char *target = t[0] == '<' ? t + 1 : t;
        target[strcspn(target, ">")] = 0;
        if (*target && !strstr(target, "://") && strncmp(target, "mailto:", 7)) {
            char *full = g_build_filename(dir, target, NULL);
            if (!g_file_test(full, G_FILE_TEST_EXISTS))
                found(f, "%s: link to %s: no such file", path, target);
            g_free(full);
        }
        g_free(t);
    }
    for (guint i = 0; i < code->len; i++) {
        GPtrArray *cmds = split_commands(code->pdata[i]);
        for (guint k = 0; k < cmds->len; k++)
            check_command(f, path, cmds->pdata[k]);
        g_ptr_array_free(cmds, TRUE);
    }
    g_free(dir);
    g_ptr_array_free(links, TRUE);
    g_ptr_array_free(code, TRUE);
    g_free(text);
}

static int count_lines(const char *path)
{
    char *text = NULL;
    gsize len = 0;
    if (!g_file_get_contents(path, &text, &len, NULL))
        return -1;
    int n = 0;
    for (gsize i = 0; i < len; i++)
        n += text[i] == '\n';
    if (len && text[len - 1] != '\n')
        n++;
    g_free(text);
    return n;
}

TEST(readme_is_at_most_300_lines)
{
    finds f;
    finds_init(&f);
    int n = f.root[0] ? count_lines("README.md") : -1;
    finds_free(&f);
    CHECK(n >= 0, "README.md not found (cwd or two levels above the binary)");
    CHECK(n > 20 && n <= README_MAX_LINES, "README.md has %d lines (at most %d)", n,
          README_MAX_LINES);
}

TEST(readme_links_and_commands_are_real)
{
    finds f;
    finds_init(&f);
    int have = f.root[0] && access(f.bin, X_OK) == 0;
    if (have)
        check_md(&f, "README.md");
    char *msg = g_strdup(f.msg->str);
    int n = f.n;
    finds_free(&f);
    if (!have) {
        g_free(msg);
        CHECK(0, "no repository root or no bin/specklab (build first)");
    }
    char m[900];
    snprintf(m, sizeof m, "%s", msg);
    g_free(msg);
    CHECK(n == 0, "%d problem(s) in README.md:%s", n, m);
}

TEST(docs_links_and_commands_are_real)
{
    finds f;
    finds_init(&f);
    int have = f.root[0] && access(f.bin, X_OK) == 0;
    int ndocs = 0;
    GDir *d = have ? g_dir_open("docs", 0, NULL) : NULL;
    for (const char *e; d && (e = g_dir_read_name(d));) {
        if (!g_str_has_suffix(e, ".md"))
            continue;
        char *p = g_build_filename("docs", e, NULL);
        check_md(&f, p);
        g_free(p);
        ndocs++;
    }
    if (d)
        g_dir_close(d);
    char m[900];
    snprintf(m, sizeof m, "%s", f.msg->str);
    int n = f.n;
    finds_free(&f);
    CHECK(have, "no repository root or no bin/specklab (build first)");
    CHECK(ndocs > 0, "no docs/*.md");
    CHECK(n == 0, "%d problem(s) in docs/:%s", n, m);
}

/* The checker itself: one mistake of each kind, each reported; the
 * correct lines around them are not. */
TEST(the_check_finds_each_kind_of_mistake)
{
    finds f;
    finds_init(&f);
    int have = f.root[0] && access(f.bin, X_OK) == 0;
    char dir[] = "/tmp/sl_readme_XXXXXX";
    int made = have && mkdtemp(dir) != NULL;
    char *md = made ? g_build_filename(dir, "bad.md", NULL) : NULL;
    const char *text =
        "# bad\n\nSee [the manual](README-gone.md), [self](bad.md#top) and\n"
        "[the web](https://example.org/x). Run `specklab binary x.fits --wds`.\n\n"
        "```sh\n"
        "bin/specklab recon their.fits --no-such-option -o image.fits   # wrong\n"
        "specklab recon their.fits --method direct --binary \\\n"
        "    --r2-px 28 -o image.fits --png image.png --json\n"
        "specklab nosuchcommand --json\n"
        "bin/specklab sim -s 3 -o x.fits\n"
        "bin/specklab camera grab --camera 127.0.0.1 --frames 10 -o g.fits\n"
        "specklab runs list --since 7d | head && specklab runs show RUN-ID\n"
        "make test && make no-such-target\n"
        "bin/specklabd --config my.conf --foreground &\n"
        "specklab COMMAND --help\n"
        "```\n";
    int wrote = md && g_file_set_contents(md, text, -1, NULL);
    if (wrote)
        check_md(&f, md);
    const char *s = f.msg->str;
    int link = strstr(s, "link to README-gone.md") != NULL;
    int opt = strstr(s, "`recon --no-such-option`") != NULL;
    int cmd = strstr(s, "`specklab nosuchcommand`") != NULL;
    int shrt = strstr(s, "`sim -s`") != NULL;
    int make = strstr(s, "`make no-such-target`") != NULL;
    char m[900];
    snprintf(m, sizeof m, "%s", s);
    int n = f.n;
    if (md) {
        unlink(md);
        rmdir(dir);
    }
    g_free(md);
    finds_free(&f);
    CHECK(have, "no repository root or no bin/specklab (build first)");
    CHECK(wrote, "writing the test file in %s", dir);
    CHECK(link && opt && cmd && shrt && make && n == 5,
          "expected exactly the 5 mistakes (link %d, option %d, command %d, short %d, "
          "make %d), found %d:%s", link, opt, cmd, shrt, make, n, m);
}

TC_MAIN(TC_CASE(readme_is_at_most_300_lines), TC_CASE(readme_links_and_commands_are_real),
        TC_CASE(docs_links_and_commands_are_real), TC_CASE(the_check_finds_each_kind_of_mistake))
