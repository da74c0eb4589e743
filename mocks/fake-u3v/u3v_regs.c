/* u3v_regs.c - GenCP over the U3V control channel: ReadMem and WriteMem
 * against the bootstrap registers, the manifest, the GenICam XML and the
 * fake camera's feature memory (u3v_regs.h has the map).
 *
 * Threads: commands arrive on the USB handler's thread, the stream thread
 * asks whether streaming is on; one lock covers the bootstrap words.  The
 * ArvFakeCamera has its own lock for its memory.
 */
#include <stdlib.h>
#include <string.h>

#include "u3v_regs.h"

#define ABRM_BASE 0x000000u
#define SBRM_BASE 0x001000u
#define SIRM_BASE 0x002000u
#define MANIFEST_BASE 0x003000u
#define BOOT_SIZE 0x004000u
#define FEATURE_BASE 0x010000u
#define XML_BASE 0x100000u

#define GENCP_MAGIC 0x43563355u /* "U3VC" */
#define GENCP_FLAG_REQUEST_ACK 0x4000u
#define CMD_READMEM 0x0800u
#define CMD_WRITEMEM 0x0802u
#define ST_SUCCESS 0x0000u
#define ST_NOT_IMPLEMENTED 0x8001u
#define ST_INVALID_PARAMETER 0x8002u
#define ST_INVALID_ADDRESS 0x8003u
#define ST_WRITE_PROTECT 0x8004u

/* SIRM words the host writes (offsets in SIRM). */
#define SIRM_CONTROL 0x04u
#define SIRM_WRITABLE_FIRST 0x18u /* max leader ... max trailer */
#define SIRM_WRITABLE_END 0x30u
#define LEADER_SIZE 52u
#define TRAILER_SIZE 32u

struct u3v_regs {
    ArvFakeCamera *fake;
    GMutex lock;
    uint8_t boot[BOOT_SIZE];
    char *xml;
    size_t xml_size;
};

static void put16(uint8_t *p, uint32_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static void put32(uint8_t *p, uint32_t v) { put16(p, v); put16(p + 2, v >> 16); }
static void put64(uint8_t *p, uint64_t v) { put32(p, (uint32_t)v); put32(p + 4, (uint32_t)(v >> 32)); }
static uint32_t get16(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8; }
static uint32_t get32(const uint8_t *p) { return get16(p) | get16(p + 2) << 16; }
static uint64_t get64(const uint8_t *p) { return get32(p) | (uint64_t)get32(p + 4) << 32; }

/* The fake camera's XML with each <Address>N</Address> moved by
 * FEATURE_BASE: the features keep their registers, seen through the
 * window.  (Its XML has no other address form: no pAddress, no
 * IntSwissKnife address.) */
static char *relocate_xml(const char *xml, size_t n, size_t *out_n)
{
    static const char tag[] = "<Address>";
    GString *s = g_string_sized_new(n + 256);
    const char *p = xml, *end = xml + n, *hit;
    while ((hit = g_strstr_len(p, end - p, tag))) {
        hit += sizeof tag - 1;
        g_string_append_len(s, p, hit - p);
        char *after = NULL;
        guint64 a = g_ascii_strtoull(hit, &after, 0);
        g_string_append_printf(s, "0x%" G_GINT64_MODIFIER "x", a + FEATURE_BASE);
        p = after;
    }
    g_string_append_len(s, p, end - p);
    *out_n = s->len;
    return g_string_free(s, FALSE);
}

static void put_str(uint8_t *p, const char *s)
{
    strncpy((char *)p, s, 63);
}

static void fill_bootstrap(u3v_regs *r, const char *vendor, const char *model,
                           const char *serial)
{
    uint8_t *abrm = r->boot + ABRM_BASE, *sbrm = r->boot + SBRM_BASE;
    uint8_t *sirm = r->boot + SIRM_BASE, *man = r->boot + MANIFEST_BASE;
    put32(abrm + 0x000, 1u << 16);         /* GenCP 1.0 */
    put_str(abrm + 0x004, vendor);
    put_str(abrm + 0x044, model);
    put_str(abrm + 0x084, "specklab mocks");
    put_str(abrm + 0x0c4, "1.0");
    put_str(abrm + 0x104, "simulated speckle camera");
    put_str(abrm + 0x144, serial);
    put64(abrm + 0x1c4, 0);                /* device capability */
    put32(abrm + 0x1cc, 200);              /* max response time, ms */
    put64(abrm + 0x1d0, MANIFEST_BASE);
    put64(abrm + 0x1d8, SBRM_BASE);
    put32(abrm + 0x208, 0xFFFFFFFFu);      /* little-endian protocol */
    put32(abrm + 0x20c, 0xFFFFFFFFu);
    put32(sbrm + 0x00, 1u << 16);          /* U3V 1.0 */
    put64(sbrm + 0x04, 1);                 /* SIRM present */
    put32(sbrm + 0x14, U3V_CMD_MAX);
    put32(sbrm + 0x18, U3V_CMD_MAX);
    put32(sbrm + 0x1c, 1);                 /* one stream channel */
    put64(sbrm + 0x20, SIRM_BASE);
    put32(sbrm + 0x28, 0x40);
    put32(sbrm + 0x40, 4);                 /* current speed: SuperSpeed */
    put32(sirm + 0x00, 0);                 /* alignment 1 byte */
    put32(sirm + 0x10, LEADER_SIZE);
    put32(sirm + 0x14, TRAILER_SIZE);
    put64(man + 0x00, 1);                  /* entries */
    put64(man + 0x08, 1u << 16);           /* file version 1.0, schema raw XML */
    put64(man + 0x10, XML_BASE);
    put64(man + 0x18, r->xml_size);
}

int u3v_regs_new(u3v_regs **out, ArvFakeCamera *fake, const char *vendor,
                 const char *model, const char *serial, sl_err *err)
{
    *out = NULL;
    u3v_regs *r = calloc(1, sizeof *r);
    if (!r)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    size_t n = 0;
    const char *xml = arv_fake_camera_get_genicam_xml(fake, &n);
    if (!xml) {
        free(r);
        return sl_seterr(err, SL_EIO, "the fake camera has no GenICam XML");
    }
    r->fake = fake;
    r->xml = relocate_xml(xml, n, &r->xml_size);
    g_mutex_init(&r->lock);
    fill_bootstrap(r, vendor, model, serial);
    *out = r;
    return SL_OK;
}

void u3v_regs_free(u3v_regs *r)
{
    if (!r)
        return;
    g_free(r->xml);
    g_mutex_clear(&r->lock);
    free(r);
}

/* The required payload follows the features (Width, Height, PixelFormat):
 * refreshed on every SIRM read, as a camera recomputes it. */
static void refresh_payload(u3v_regs *r)
{
    put64(r->boot + SIRM_BASE + 0x08, arv_fake_camera_get_payload(r->fake));
}

static uint32_t read_mem(u3v_regs *r, uint64_t a, uint32_t n, uint8_t *dst)
{
    if (a + n <= BOOT_SIZE) {
        g_mutex_lock(&r->lock);
        refresh_payload(r);
        memcpy(dst, r->boot + a, n);
        g_mutex_unlock(&r->lock);
        return ST_SUCCESS;
    }
    if (a >= FEATURE_BASE && a + n <= FEATURE_BASE + ARV_FAKE_CAMERA_MEMORY_SIZE)
        return arv_fake_camera_read_memory(r->fake, (guint32)(a - FEATURE_BASE), n, dst)
                   ? ST_SUCCESS : ST_INVALID_ADDRESS;
    if (a >= XML_BASE && a + n <= XML_BASE + r->xml_size) {
        memcpy(dst, r->xml + (a - XML_BASE), n);
        return ST_SUCCESS;
    }
    return ST_INVALID_ADDRESS;
}

static uint32_t write_mem(u3v_regs *r, uint64_t a, uint32_t n, const uint8_t *src)
{
    if (a >= FEATURE_BASE && a + n <= FEATURE_BASE + ARV_FAKE_CAMERA_MEMORY_SIZE)
        return arv_fake_camera_write_memory(r->fake, (guint32)(a - FEATURE_BASE), n, src)
                   ? ST_SUCCESS : ST_INVALID_ADDRESS;
    if (a + n > BOOT_SIZE && a < XML_BASE + r->xml_size)
        return ST_INVALID_ADDRESS;
    uint64_t rel = a - SIRM_BASE;
    int sirm_ok = a >= SIRM_BASE &&
                  ((rel == SIRM_CONTROL && n == 4) ||
                   (rel >= SIRM_WRITABLE_FIRST && rel + n <= SIRM_WRITABLE_END));
    if (!sirm_ok)
        return ST_WRITE_PROTECT;
    g_mutex_lock(&r->lock);
    memcpy(r->boot + a, src, n);
    g_mutex_unlock(&r->lock);
    return ST_SUCCESS;
}

static int ack_header(uint8_t *ack, uint32_t status, uint32_t cmd, uint32_t size,
                      uint32_t id)
{
    put32(ack, GENCP_MAGIC);
    put16(ack + 4, status);
    put16(ack + 6, cmd + 1);
    put16(ack + 8, size);
    put16(ack + 10, id);
    return 12 + (int)size;
}

int u3v_regs_command(u3v_regs *r, const uint8_t *cmd, size_t n, uint8_t *ack)
{
    if (n < 12 || get32(cmd) != GENCP_MAGIC)
        return -1;
    uint32_t flags = get16(cmd + 4), code = get16(cmd + 6);
    uint32_t size = get16(cmd + 8), id = get16(cmd + 10);
    const uint8_t *body = cmd + 12;
    if (12 + (size_t)size > n)
        return -1;
    int len;
    if (code == CMD_READMEM && size >= 12) {
        uint64_t a = get64(body);
        uint32_t want = get16(body + 10);
        uint32_t st = want > U3V_CMD_MAX - 12 ? ST_INVALID_PARAMETER
                                              : read_mem(r, a, want, ack + 12);
        len = ack_header(ack, st, code, st == ST_SUCCESS ? want : 0, id);
    } else if (code == CMD_WRITEMEM && size >= 8) {
        uint32_t st = write_mem(r, get64(body), size - 8, body + 8);
        len = ack_header(ack, st, code, 4, id);
        put16(ack + 12, 0);
        put16(ack + 14, st == ST_SUCCESS ? size - 8 : 0);
    } else {
        len = ack_header(ack, ST_NOT_IMPLEMENTED, code, 0, id);
    }
    return flags & GENCP_FLAG_REQUEST_ACK ? len : 0;
}

void u3v_regs_reset(u3v_regs *r)
{
    g_mutex_lock(&r->lock);
    put32(r->boot + SIRM_BASE + SIRM_CONTROL, 0);
    memset(r->boot + SIRM_BASE + SIRM_WRITABLE_FIRST, 0, SIRM_WRITABLE_END - SIRM_WRITABLE_FIRST);
    g_mutex_unlock(&r->lock);
}

int u3v_regs_stream_enabled(u3v_regs *r)
{
    g_mutex_lock(&r->lock);
    int on = (int)(get32(r->boot + SIRM_BASE + SIRM_CONTROL) & 1u);
    g_mutex_unlock(&r->lock);
    return on;
}

size_t u3v_regs_payload_size(u3v_regs *r)
{
    return arv_fake_camera_get_payload(r->fake);
}
