/* A small C layer over the system's libjpeg (libjpeg-turbo), for src/io/codec/jpeg.rs.
 *
 * libjpeg reports fatal errors through error_exit, which must not return; the standard way
 * (libjpeg.txt, "Error handling"; example.c) is a setjmp in the caller and a longjmp from
 * error_exit. Every function here that calls into libjpeg sets its own jump point, so a
 * longjmp never crosses a Rust frame: Rust sees a return code and the message.
 * Warnings are not printed (libjpeg prints them to stderr by default); a premature end of
 * data (or scan data cut short by a marker) is remembered: Rust treats it as an error
 * rather than accept made-up grey. */
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jerror.h>
#include <jpeglib.h>

struct hj_err {
    struct jpeg_error_mgr pub;
    jmp_buf jump;
    char msg[JMSG_LENGTH_MAX];
    int eof;
};

typedef struct {
    struct jpeg_decompress_struct cinfo;
    struct hj_err err;
    int started;
} hj;

static void hj_error_exit(j_common_ptr cinfo) {
    struct hj_err *e = (struct hj_err *)cinfo->err;
    (*cinfo->err->format_message)(cinfo, e->msg);
    longjmp(e->jump, 1);
}

static void hj_emit_message(j_common_ptr cinfo, int level) {
    struct hj_err *e = (struct hj_err *)cinfo->err;
    if (level < 0) {
        if (cinfo->err->msg_code == JWRN_JPEG_EOF || cinfo->err->msg_code == JWRN_HIT_MARKER) {
            e->eof = 1;
        }
        cinfo->err->num_warnings++;
    }
}

static void hj_copy(const char *src, char *dst, size_t len) {
    if (len == 0) return;
    strncpy(dst, src, len - 1);
    dst[len - 1] = 0;
}

/* Opens `data` and reads its header. Returns NULL with the message in `msg` on failure. */
void *hj_open(const unsigned char *data, unsigned long len, char *msg, unsigned long msg_len) {
    hj *h = (hj *)calloc(1, sizeof(hj));
    if (!h) {
        hj_copy("out of memory", msg, msg_len);
        return NULL;
    }
    h->cinfo.err = jpeg_std_error(&h->err.pub);
    h->err.pub.error_exit = hj_error_exit;
    h->err.pub.emit_message = hj_emit_message;
    if (setjmp(h->err.jump)) {
        hj_copy(h->err.msg, msg, msg_len);
        jpeg_destroy_decompress(&h->cinfo);
        free(h);
        return NULL;
    }
    jpeg_create_decompress(&h->cinfo);
    jpeg_mem_src(&h->cinfo, data, len);
    jpeg_read_header(&h->cinfo, TRUE);
    return h;
}

/* The header's facts: size, components, colour space (J_COLOR_SPACE), progressive. */
void hj_info(void *p, unsigned *w, unsigned *hgt, int *components, int *color_space,
             int *progressive) {
    hj *h = (hj *)p;
    *w = h->cinfo.image_width;
    *hgt = h->cinfo.image_height;
    *components = h->cinfo.num_components;
    *color_space = (int)h->cinfo.jpeg_color_space;
    *progressive = h->cinfo.progressive_mode ? 1 : 0;
}

/* Starts decompression at 1/`denom` scale (1, 2, 4 or 8) into grey (`gray` != 0) or RGB.
 * Returns 0, or -1 with the message. The output size goes to out_w, out_h. */
int hj_start(void *p, int denom, int gray, unsigned *out_w, unsigned *out_h, char *msg,
             unsigned long msg_len) {
    hj *h = (hj *)p;
    if (setjmp(h->err.jump)) {
        hj_copy(h->err.msg, msg, msg_len);
        return -1;
    }
    h->cinfo.scale_num = 1;
    h->cinfo.scale_denom = (unsigned)denom;
    h->cinfo.out_color_space = gray ? JCS_GRAYSCALE : JCS_RGB;
    /* The accurate integer IDCT (libjpeg's default) and fancy upsampling: the best quality
     * libjpeg offers, as the image crate's decoder also aims for. */
    h->cinfo.dct_method = JDCT_ISLOW;
    h->cinfo.do_fancy_upsampling = TRUE;
    jpeg_start_decompress(&h->cinfo);
    h->started = 1;
    *out_w = h->cinfo.output_width;
    *out_h = h->cinfo.output_height;
    return 0;
}

/* Reads `rows` rows into `buf` (rows `stride` bytes apart). Returns the rows read (fewer
 * only at the end of the image), or -1 with the message; *eof is set when the data ended
 * early. */
long hj_read(void *p, unsigned char *buf, unsigned long rows, unsigned long stride, int *eof,
             char *msg, unsigned long msg_len) {
    hj *h = (hj *)p;
    /* volatile: changed between setjmp and a possible longjmp. */
    volatile unsigned long done = 0;
    if (setjmp(h->err.jump)) {
        hj_copy(h->err.msg, msg, msg_len);
        return -1;
    }
    while (done < rows && h->cinfo.output_scanline < h->cinfo.output_height) {
        JSAMPROW row[1];
        row[0] = buf + done * stride;
        done += jpeg_read_scanlines(&h->cinfo, row, 1);
    }
    *eof = h->err.eof;
    return (long)done;
}

/* Frees everything (abandoning a decode that has not finished). */
void hj_close(void *p) {
    hj *h = (hj *)p;
    if (!h) return;
    jpeg_destroy_decompress(&h->cinfo);
    free(h);
}
