/* sniffer._hot: the offline per-frame path in C, built when a compiler is there (setup.py).

   Each function here is a copy of a pure-Python function that stays the reference (named beside each);
   tests/test_hot_equal.py holds the two byte for byte.  Where a case is rare or unusual, these functions
   do not decide it: they stop and return where the Python code carries on, so every odd input (damaged
   bytes, a JSON message written by another tool, a number past 64 bits) takes the reference path.
   sniffer/hot.py loads this module (or says why not); SNIFFER_PURE=1 leaves it out.
*/
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

#define CAN_REQ 1
#define CAN_RSP 2

static uint16_t crc_table[256];

static void crc_init(void)
{
    for (int v = 0; v < 256; v++) {
        uint16_t s = (uint16_t)v;
        for (int k = 0; k < 8; k++)
            s = (s & 1) ? (uint16_t)((s >> 1) ^ 0xA001) : (uint16_t)(s >> 1);
        crc_table[v] = s;
    }
}

/* CRC-16/MODBUS (reflected 0xA001, init 0xFFFF): 0 over a frame and its own CRC (framing/crc.py crc16_raw) */
static inline uint16_t crc16(const unsigned char *p, Py_ssize_t n)
{
    uint16_t c = 0xFFFF;
    while (n-- > 0)
        c = (uint16_t)((c >> 8) ^ crc_table[(c ^ *p++) & 0xFF]);
    return c;
}

static PyObject *py_crc16(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) < 0)
        return NULL;
    uint16_t c = crc16((const unsigned char *)b.buf, b.len);
    PyBuffer_Release(&b);
    return PyLong_FromLong(c);
}

/* ------------------------------------------------------------------ RTU rule A (framing/rtu.py) */

typedef struct {
    int n;
    int len[2];
    int can[2];
} cands_t;

/* rtu.py _quick: candidates (length, roles), shortest first; 0 where the full rules apply */
static int quick(const unsigned char *b, Py_ssize_t i, Py_ssize_t n, cands_t *c)
{
    unsigned u = b[i];
    if (!(u > 0 && u <= 247))
        return 0;
    unsigned fc = b[i + 1];
    if (fc >= 1 && fc <= 4) {
        int lr = b[i + 2] + 5;
        if (lr < 8) {
            c->n = 2; c->len[0] = lr; c->can[0] = CAN_RSP; c->len[1] = 8; c->can[1] = CAN_REQ;
        } else if (lr == 8) {
            c->n = 1; c->len[0] = 8; c->can[0] = CAN_REQ | CAN_RSP;
        } else {
            c->n = 2; c->len[0] = 8; c->can[0] = CAN_REQ; c->len[1] = lr; c->can[1] = CAN_RSP;
        }
        return 1;
    }
    if (fc == 5 || fc == 6 || fc == 8) {
        c->n = 1; c->len[0] = 8; c->can[0] = CAN_REQ | CAN_RSP;
        return 1;
    }
    if (fc == 0x10 || fc == 0x0F) {
        if (i + 8 > n) {
            c->n = 1; c->len[0] = 8; c->can[0] = CAN_RSP;
        } else {
            c->n = 2; c->len[0] = 8; c->can[0] = CAN_RSP; c->len[1] = b[i + 6] + 9; c->can[1] = CAN_REQ;
        }
        return 1;
    }
    if ((fc & 0x80) && fc != 0x80) {
        c->n = 1; c->len[0] = 5; c->can[0] = CAN_RSP;
        return 1;
    }
    return 0;
}

static PyObject *s_buf, *s_base, *s_pos, *s_avail, *s_segs, *s_data, *s_byte_t_ns, *s_t_ns, *s_channel, *s_char_ns,
    *s_index, *s_prev_frame_end_ns, *s_need, *s_is_boundary, *s_time_source, *s_adu, *s_read, *s_modbus_rtu;

/* an attribute as a C int64; -1 with an exception set (OverflowError for a number past 64 bits) */
static int get_i64(PyObject *o, PyObject *name, int64_t *out)
{
    PyObject *v = PyObject_GetAttr(o, name);
    if (v == NULL)
        return -1;
    long long x = PyLong_AsLongLong(v);
    Py_DECREF(v);
    if (x == -1 && PyErr_Occurred())
        return -1;
    *out = x;
    return 0;
}

/* segs[k] -> (start, chunk, end, per_byte); -1 with an exception set */
static int seg_at(PyObject *segs, Py_ssize_t k, int64_t *start, PyObject **chunk, int64_t *end, int *per_byte)
{
    PyObject *item = PySequence_GetItem(segs, k);
    if (item == NULL)
        return -1;
    if (!PyTuple_Check(item) || PyTuple_GET_SIZE(item) != 2) {
        Py_DECREF(item);
        PyErr_SetString(PyExc_TypeError, "segs holds (start, Chunk) pairs");
        return -1;
    }
    long long s = PyLong_AsLongLong(PyTuple_GET_ITEM(item, 0));
    if (s == -1 && PyErr_Occurred()) {
        Py_DECREF(item);
        return -1;
    }
    PyObject *c = PyTuple_GET_ITEM(item, 1);
    Py_INCREF(c);
    Py_DECREF(item);
    PyObject *d = PyObject_GetAttr(c, s_data);
    if (d == NULL) {
        Py_DECREF(c);
        return -1;
    }
    Py_ssize_t n = PyObject_Length(d);
    Py_DECREF(d);
    if (n < 0) {
        Py_DECREF(c);
        return -1;
    }
    PyObject *bt = PyObject_GetAttr(c, s_byte_t_ns);
    if (bt == NULL) {
        Py_DECREF(c);
        return -1;
    }
    *per_byte = bt != Py_None;
    Py_DECREF(bt);
    *start = s;
    *end = s + n;
    *chunk = c;
    return 0;
}

/* the framer's state written back: index, prev_frame_end_ns, pos (and _need when need >= 0) */
static int save_state(PyObject *fr, int64_t index, int has_prev, int64_t prev_end, int64_t p, int64_t need)
{
    PyObject *v = PyLong_FromLongLong(index);
    if (v == NULL || PyObject_SetAttr(fr, s_index, v) < 0)
        goto fail;
    Py_DECREF(v);
    v = has_prev ? PyLong_FromLongLong(prev_end) : Py_NewRef(Py_None);
    if (v == NULL || PyObject_SetAttr(fr, s_prev_frame_end_ns, v) < 0)
        goto fail;
    Py_DECREF(v);
    v = PyLong_FromLongLong(p);
    if (v == NULL || PyObject_SetAttr(fr, s_pos, v) < 0)
        goto fail;
    Py_DECREF(v);
    if (need >= 0) {
        v = PyLong_FromLongLong(need);
        if (v == NULL || PyObject_SetAttr(fr, s_need, v) < 0)
            goto fail;
        Py_DECREF(v);
    }
    return 0;
fail:
    Py_XDECREF(v);
    return -1;
}

/* self._is_boundary(e, limit, final): 1 True, 0 False, 2 None (unknown yet), -1 error */
static int call_is_boundary(PyObject *fr, int64_t e, int64_t limit, int final)
{
    PyObject *pe = PyLong_FromLongLong(e), *pl = PyLong_FromLongLong(limit);
    if (pe == NULL || pl == NULL) {
        Py_XDECREF(pe);
        Py_XDECREF(pl);
        return -1;
    }
    PyObject *r = PyObject_CallMethodObjArgs(fr, s_is_boundary, pe, pl, final ? Py_True : Py_False, NULL);
    Py_DECREF(pe);
    Py_DECREF(pl);
    if (r == NULL)
        return -1;
    int out;
    if (r == Py_None)
        out = 2;
    else {
        out = PyObject_IsTrue(r);
    }
    Py_DECREF(r);
    return out;
}

#define MUL_SUB(res, a, b, c) (__builtin_mul_overflow((b), (c), &(res)) || __builtin_sub_overflow((a), (res), &(res)))

/* rtu.py RtuFramer._fast(out), its loop in C: rtu_fast(framer, out, Frame, roles) -> bool.
   Same decisions; where an int does not fit 64 bits it stops (False) and _step carries on, as it does
   after any byte _fast cannot settle alone. */
static PyObject *rtu_fast(PyObject *self, PyObject *args)
{
    PyObject *fr, *out, *frame_cls, *roles_fn;
    if (!PyArg_ParseTuple(args, "OO!OO", &fr, &PyList_Type, &out, &frame_cls, &roles_fn))
        return NULL;
    PyObject *buf = NULL, *segs = NULL, *c0 = NULL, *data = NULL, *tsrc = NULL;
    PyObject *result = NULL;
    int64_t base, p, char_ns, index, prev_end = 0, limit;
    int has_prev, final;

    buf = PyObject_GetAttr(fr, s_buf);
    if (buf == NULL || !PyByteArray_Check(buf)) {
        if (buf != NULL)
            PyErr_SetString(PyExc_TypeError, "framer.buf is a bytearray");
        goto done;
    }
    if (get_i64(fr, s_base, &base) < 0 || get_i64(fr, s_pos, &p) < 0 || get_i64(fr, s_char_ns, &char_ns) < 0
        || get_i64(fr, s_index, &index) < 0)
        goto bail_early;
    {
        PyObject *pe = PyObject_GetAttr(fr, s_prev_frame_end_ns);
        if (pe == NULL)
            goto done;
        has_prev = pe != Py_None;
        if (has_prev) {
            prev_end = PyLong_AsLongLong(pe);
            if (prev_end == -1 && PyErr_Occurred()) {
                Py_DECREF(pe);
                goto bail_early;
            }
        }
        Py_DECREF(pe);
    }
    {
        PyObject *pp = PyLong_FromLongLong(p);
        if (pp == NULL)
            goto done;
        PyObject *av = PyObject_CallMethodObjArgs(fr, s_avail, pp, NULL);
        Py_DECREF(pp);
        if (av == NULL)
            goto done;
        if (!PyTuple_Check(av) || PyTuple_GET_SIZE(av) != 2) {
            Py_DECREF(av);
            PyErr_SetString(PyExc_TypeError, "_avail gives (limit, final)");
            goto done;
        }
        limit = PyLong_AsLongLong(PyTuple_GET_ITEM(av, 0));
        final = PyObject_IsTrue(PyTuple_GET_ITEM(av, 1));
        Py_DECREF(av);
        if ((limit == -1 && PyErr_Occurred()) || final < 0)
            goto bail_early;
    }
    segs = PyObject_GetAttr(fr, s_segs);
    if (segs == NULL)
        goto done;
    Py_ssize_t nseg = PyObject_Length(segs);
    if (nseg < 0)
        goto done;
    Py_ssize_t k = 0;
    int64_t s0, end0;
    int per_byte;
    for (;;) {
        if (k >= nseg) {
            result = Py_NewRef(Py_False);
            goto done;
        }
        if (seg_at(segs, k, &s0, &c0, &end0, &per_byte) < 0)
            goto bail_early;
        if (p < end0)
            break;
        Py_CLEAR(c0);
        k++;
    }
    if (per_byte) {
        result = Py_NewRef(Py_False);
        goto done;
    }
    {
        PyObject *ts = PyObject_GetAttr(fr, s_time_source);
        if (ts == NULL)
            goto done;
        int t = PyObject_IsTrue(ts);
        if (t < 0) {
            Py_DECREF(ts);
            goto done;
        }
        if (t)
            tsrc = ts;
        else {
            Py_DECREF(ts);
            tsrc = Py_NewRef(s_read);
        }
    }
    {
        Py_ssize_t blen = PyByteArray_GET_SIZE(buf);
        int64_t a = p - base, b = limit - base;
        if (a < 0) a = 0;
        if (b > blen) b = blen;
        if (b < a) b = a;
        data = PyBytes_FromStringAndSize(PyByteArray_AS_STRING(buf) + a, (Py_ssize_t)(b - a));
        if (data == NULL)
            goto done;
    }
    const unsigned char *d = (const unsigned char *)PyBytes_AS_STRING(data);
    int64_t lim = limit - p;  /* (limit - base) - (p - base), as _fast's lim */
    int64_t p0 = p;
    int64_t c0_tns;
    if (get_i64(c0, s_t_ns, &c0_tns) < 0)
        goto bail;
    for (;;) {
        int64_t i = p - p0;
        if (i + 5 > lim)
            break;
        cands_t cands;
        if (!quick(d, (Py_ssize_t)i, (Py_ssize_t)lim, &cands))
            break;
        int length = 0, can = 0;
        for (int j = 0; j < cands.n; j++) {
            int n = cands.len[j];
            can = cands.can[j];
            if (i + n > lim) {
                if (!final) {
                    if (save_state(fr, index, has_prev, prev_end, p, p + n) < 0)
                        goto done;
                    result = Py_NewRef(Py_True);
                    goto done;
                }
                break;
            }
            if (crc16(d + i, n) == 0) {
                length = n;
                break;
            }
        }
        if (!length)
            break;
        int64_t e = p + length;
        if (cands.len[cands.n - 1] != length) {
            int at = call_is_boundary(fr, e, limit, final);
            if (at < 0)
                goto done;
            if (at != 1) {  /* False (0) or None (2) */
                for (int j = 0; j < cands.n; j++) {
                    int n2 = cands.len[j];
                    if (n2 <= length)
                        continue;
                    if (at == 2 || i + n2 > lim) {
                        if (final && at != 2)
                            continue;
                        if (save_state(fr, index, has_prev, prev_end, p, at == 2 ? e + 1 : p + n2) < 0)
                            goto done;
                        result = Py_NewRef(Py_True);
                        goto done;
                    }
                    if (crc16(d + i, n2) == 0) {
                        int at2 = call_is_boundary(fr, p + n2, limit, final);
                        if (at2 < 0)
                            goto done;
                        if (at2 == 2) {
                            if (save_state(fr, index, has_prev, prev_end, p, p + n2 + 1) < 0)
                                goto done;
                            result = Py_NewRef(Py_True);
                            goto done;
                        }
                        if (at2) {
                            if (save_state(fr, index, has_prev, prev_end, p, -1) < 0)
                                goto done;
                            result = Py_NewRef(Py_False);
                            goto done;
                        }
                    }
                }
            }
        }
        int64_t t0, t1, tmp;
        if (MUL_SUB(tmp, c0_tns, end0 - p, char_ns))
            goto bail_clear;
        t0 = tmp;
        while (e > end0) {  /* the frame ends in a later read */
            k++;
            if (k >= nseg)
                goto bail_clear;
            Py_CLEAR(c0);
            if (seg_at(segs, k, &s0, &c0, &end0, &per_byte) < 0)
                goto bail;
            if (get_i64(c0, s_t_ns, &c0_tns) < 0)
                goto bail;
            if (per_byte) {
                if (save_state(fr, index, has_prev, prev_end, p, -1) < 0)
                    goto done;
                result = Py_NewRef(Py_False);
                goto done;
            }
        }
        if (MUL_SUB(tmp, c0_tns, end0 - e, char_ns))
            goto bail_clear;
        t1 = tmp;
        int64_t idle = 0;
        if (has_prev && __builtin_sub_overflow(t0, prev_end, &idle))
            goto bail_clear;
        PyObject *raw = PyBytes_FromStringAndSize((const char *)d + i, length);
        if (raw == NULL)
            goto done;
        if (can == 3 && d[i + 1] < 5) {  /* 01-04 in 8 bytes with byte count 3: the bytes may decide the role */
            PyObject *adu = PyBytes_FromStringAndSize((const char *)d + i, length - 2);
            PyObject *r = adu == NULL ? NULL : PyObject_CallFunction(roles_fn, "Oi", adu, can);
            Py_XDECREF(adu);
            if (r == NULL) {
                Py_DECREF(raw);
                goto done;
            }
            long c = PyTuple_Check(r) && PyTuple_GET_SIZE(r) >= 1 ? PyLong_AsLong(PyTuple_GET_ITEM(r, 0)) : -1;
            Py_DECREF(r);
            if (c == -1) {
                Py_DECREF(raw);
                if (!PyErr_Occurred())
                    PyErr_SetString(PyExc_TypeError, "roles gives (can, why)");
                goto done;
            }
            can = (int)c;
        }
        PyObject *channel = PyObject_GetAttr(c0, s_channel);
        PyObject *a[14];
        a[0] = PyLong_FromLongLong(index);
        a[1] = PyLong_FromLongLong(t0);
        a[2] = PyLong_FromLongLong(t1);
        a[3] = raw;
        a[4] = s_modbus_rtu;
        a[5] = PyLong_FromLong(d[i]);
        a[6] = PyLong_FromLong(d[i + 1]);
        a[7] = PyLong_FromLong(can);
        a[8] = Py_True;
        a[9] = Py_None;
        a[10] = tsrc;
        a[11] = has_prev ? PyLong_FromLongLong(idle) : Py_NewRef(Py_None);
        a[12] = Py_None;
        a[13] = channel;
        PyObject *frame = NULL;
        if (channel && a[0] && a[1] && a[2] && a[5] && a[6] && a[7] && a[11])
            frame = PyObject_Vectorcall(frame_cls, a, 14, NULL);
        Py_XDECREF(a[0]);
        Py_XDECREF(a[1]);
        Py_XDECREF(a[2]);
        Py_XDECREF(a[5]);
        Py_XDECREF(a[6]);
        Py_XDECREF(a[7]);
        Py_XDECREF(a[11]);
        Py_XDECREF(channel);
        Py_DECREF(raw);
        if (frame == NULL)
            goto done;
        PyObject *adu = PyBytes_FromStringAndSize((const char *)d + i, length - 2);
        int bad = adu == NULL || PyObject_SetAttr(frame, s_adu, adu) < 0 || PyList_Append(out, frame) < 0;
        Py_XDECREF(adu);
        Py_DECREF(frame);
        if (bad)
            goto done;
        index++;
        has_prev = 1;
        prev_end = t1;
        p = e;
        if (e >= end0) {
            k++;
            if (k >= nseg)
                break;
            Py_CLEAR(c0);
            if (seg_at(segs, k, &s0, &c0, &end0, &per_byte) < 0)
                goto bail;
            if (per_byte)
                break;
            if (get_i64(c0, s_t_ns, &c0_tns) < 0)
                goto bail;
        }
    }
    if (save_state(fr, index, has_prev, prev_end, p, -1) < 0)
        goto done;
    result = Py_NewRef(Py_False);
    goto done;

bail:  /* a number past 64 bits: stop here; _step decides from p on (an error other than that is raised) */
    if (!PyErr_ExceptionMatches(PyExc_OverflowError))
        goto done;
    PyErr_Clear();
bail_clear:
    if (save_state(fr, index, has_prev, prev_end, p, -1) < 0)
        goto done;
    result = Py_NewRef(Py_False);
    goto done;
bail_early:  /* before anything changed: leave every byte to _step */
    if (PyErr_Occurred()) {
        if (!PyErr_ExceptionMatches(PyExc_OverflowError))
            goto done;
        PyErr_Clear();
    }
    result = Py_NewRef(Py_False);
done:
    Py_XDECREF(buf);
    Py_XDECREF(segs);
    Py_XDECREF(c0);
    Py_XDECREF(data);
    Py_XDECREF(tsrc);
    return result;
}

/* ------------------------------------------------------------------ MCAP (formats/mcap/scan.py) */

static PyObject *s_channel_id, *s_sequence, *s_log_time, *s_publish_time, *msg_kwnames;

static inline uint64_t le64(const unsigned char *b)
{
    uint64_t v = 0;
    for (int k = 7; k >= 0; k--)
        v = (v << 8) | b[k];
    return v;
}

/* scan.py _walk_chunk's loop over plain messages: chunk_messages(data, pos, skipped, Message, out) -> pos.
   Appends a Message for every message record from pos whose channel id is not in `skipped`; stops at the
   first record that is not a well-formed message (a channel, a schema, a record cut off or too short: the
   Python loop reads that one) and returns where it stopped (len(data) at the end). */
static PyObject *chunk_messages(PyObject *self, PyObject *args)
{
    Py_buffer b;
    Py_ssize_t pos;
    PyObject *skipped, *msg_cls, *out;
    if (!PyArg_ParseTuple(args, "y*nOOO!", &b, &pos, &skipped, &msg_cls, &PyList_Type, &out))
        return NULL;
    const unsigned char *d = (const unsigned char *)b.buf;
    Py_ssize_t n = b.len;
    int is_set = PyAnySet_Check(skipped);
    while (pos >= 0 && pos < n) {
        if (n - pos < 9)
            break;
        unsigned op = d[pos];
        uint64_t length = le64(d + pos + 1);
        if (op != 0x05 || length < 22 || length > (uint64_t)(n - pos - 9))
            break;
        const unsigned char *m = d + pos + 9;
        unsigned cid = m[0] | (m[1] << 8);
        PyObject *pcid = PyLong_FromUnsignedLong(cid);
        if (pcid == NULL)
            goto fail;
        int skip = is_set ? PySet_Contains(skipped, pcid) : PySequence_Contains(skipped, pcid);
        if (skip < 0) {
            Py_DECREF(pcid);
            goto fail;
        }
        if (!skip) {
            uint32_t seq = (uint32_t)m[2] | ((uint32_t)m[3] << 8) | ((uint32_t)m[4] << 16) | ((uint32_t)m[5] << 24);
            PyObject *a[5];
            a[0] = pcid;
            a[1] = PyLong_FromUnsignedLong(seq);
            a[2] = PyLong_FromUnsignedLongLong(le64(m + 6));
            a[3] = PyLong_FromUnsignedLongLong(le64(m + 14));
            a[4] = PyBytes_FromStringAndSize((const char *)m + 22, (Py_ssize_t)length - 22);
            PyObject *msg = NULL;
            if (a[1] && a[2] && a[3] && a[4])
                msg = PyObject_Vectorcall(msg_cls, a, 0, msg_kwnames);
            for (int k = 0; k < 5; k++)
                Py_XDECREF(a[k]);
            if (msg == NULL)
                goto fail;
            int bad = PyList_Append(out, msg);
            Py_DECREF(msg);
            if (bad < 0)
                goto fail;
        } else {
            Py_DECREF(pcid);
        }
        pos += 9 + (Py_ssize_t)length;
    }
    PyBuffer_Release(&b);
    return PyLong_FromSsize_t(pos);
fail:
    PyBuffer_Release(&b);
    return NULL;
}


/* scan.py Scan._past_indexes' inner loop: index_run(buf) -> bytes of buf that are whole, well-formed message
   index records, from its start (the Python loop's `i`) */
static PyObject *index_run(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_SIMPLE) < 0)
        return NULL;
    const unsigned char *d = (const unsigned char *)b.buf;
    Py_ssize_t n = b.len, i = 0;
    while (i + 15 <= n) {
        uint64_t length = le64(d + i + 1);
        if (d[i] != 0x07 || length > (uint64_t)(n - i - 9) || length < 6 || (length - 6) % 16)
            break;
        uint32_t count = (uint32_t)d[i + 11] | ((uint32_t)d[i + 12] << 8) | ((uint32_t)d[i + 13] << 16)
                         | ((uint32_t)d[i + 14] << 24);
        if ((uint64_t)count != length - 6)
            break;
        i += 9 + (Py_ssize_t)length;
    }
    PyBuffer_Release(&b);
    return PyLong_FromSsize_t(i);
}

/* ------------------------------------------------------------------ /raw events (formats/mcap/format.py) */

static int hexval(unsigned char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

typedef struct {
    const unsigned char *p, *end;
} cur_t;

static int lit(cur_t *c, const char *s)
{
    size_t n = strlen(s);
    if ((size_t)(c->end - c->p) < n || memcmp(c->p, s, n) != 0)
        return 0;
    c->p += n;
    return 1;
}

/* a JSON integer of at most 18 digits (no sign but '-', no fraction or exponent) */
static int int18(cur_t *c, int64_t *out)
{
    int neg = 0, nd = 0;
    int64_t v = 0;
    if (c->p < c->end && *c->p == '-') {
        neg = 1;
        c->p++;
    }
    if (c->p < c->end && *c->p == '0' && c->p + 1 < c->end && c->p[1] >= '0' && c->p[1] <= '9')
        return 0;  /* a leading zero: not JSON; the reference says so */
    while (c->p < c->end && *c->p >= '0' && *c->p <= '9') {
        if (++nd > 18)
            return 0;
        v = v * 10 + (*c->p++ - '0');
    }
    if (!nd)
        return 0;
    if (c->p < c->end && (*c->p == '.' || *c->p == 'e' || *c->p == 'E'))
        return 0;
    *out = neg ? -v : v;
    return 1;
}

/* a JSON string of printable ASCII without escapes: [start, end) of its text */
static int simple_str(cur_t *c, const unsigned char **s, Py_ssize_t *n)
{
    if (c->p >= c->end || *c->p != '"')
        return 0;
    const unsigned char *q = ++c->p;
    while (q < c->end && *q != '"') {
        if (*q == '\\' || *q < 0x20 || *q >= 0x7F)
            return 0;
        q++;
    }
    if (q >= c->end)
        return 0;
    *s = c->p;
    *n = q - c->p;
    c->p = q + 1;
    return 1;
}

static PyObject *s_empty;

/* format.py decode_event for the messages this sniffer writes: decode_chunk(data, Chunk, Tick) -> event, or
   None where the message has another shape (flags, unseen_ns, de, packet, a gap, escapes, other key order,
   numbers past 18 digits ...): decode_event reads those. */
static PyObject *decode_raw(PyObject *self, PyObject *args)
{
    Py_buffer b;
    PyObject *chunk_cls, *tick_cls;
    if (!PyArg_ParseTuple(args, "y*OO", &b, &chunk_cls, &tick_cls))
        return NULL;
    cur_t c = {(const unsigned char *)b.buf, (const unsigned char *)b.buf + b.len};
    PyObject *result = NULL, *raw = NULL, *bt = NULL, *ch = NULL, *link = NULL;
    int64_t t;
    int is_tick = 0;
    if (lit(&c, "{\"kind\":\"tick\",\"t_ns\":"))
        is_tick = 1;
    else if (!lit(&c, "{\"kind\":\"chunk\",\"t_ns\":"))
        goto none;
    if (!int18(&c, &t))
        goto none;
    if (!is_tick) {
        if (!lit(&c, ",\"data\":\""))
            goto none;
        const unsigned char *h = c.p;
        while (c.p < c.end && *c.p != '"')
            c.p++;
        if (c.p >= c.end || (c.p - h) % 2)
            goto none;
        Py_ssize_t nb = (c.p - h) / 2;
        raw = PyBytes_FromStringAndSize(NULL, nb);
        if (raw == NULL)
            goto fail;
        unsigned char *r = (unsigned char *)PyBytes_AS_STRING(raw);
        for (Py_ssize_t k = 0; k < nb; k++) {
            int hi = hexval(h[2 * k]), lo = hexval(h[2 * k + 1]);
            if (hi < 0 || lo < 0)
                goto none;
            r[k] = (unsigned char)(hi << 4 | lo);
        }
        c.p++;
        if (lit(&c, ",\"byte_dt_ns\":null")) {
            bt = Py_NewRef(Py_None);
        } else if (lit(&c, ",\"byte_dt_ns\":[")) {
            bt = PyTuple_New(nb);
            if (bt == NULL)
                goto fail;
            for (Py_ssize_t k = 0; k < nb; k++) {
                int64_t x, s;
                if (k && !lit(&c, ","))
                    goto none;
                if (!int18(&c, &x) || __builtin_add_overflow(t, x, &s))
                    goto none;
                PyObject *v = PyLong_FromLongLong(s);
                if (v == NULL)
                    goto fail;
                PyTuple_SET_ITEM(bt, k, v);
            }
            if (!lit(&c, "]"))
                goto none;  /* fewer or more offsets than bytes: decode_event says which */
        } else
            goto none;
        const unsigned char *s;
        Py_ssize_t n;
        if (!lit(&c, ",\"flags\":[],\"channel\":") || !simple_str(&c, &s, &n))
            goto none;
        ch = n ? PyUnicode_FromStringAndSize((const char *)s, n) : Py_NewRef(s_empty);
        if (ch == NULL)
            goto fail;
    }
    if (lit(&c, ",\"link\":")) {
        const unsigned char *s;
        Py_ssize_t n;
        if (!simple_str(&c, &s, &n))
            goto none;
        link = n ? PyUnicode_FromStringAndSize((const char *)s, n) : Py_NewRef(s_empty);
        if (link == NULL)
            goto fail;
    } else
        link = Py_NewRef(s_empty);
    if (!lit(&c, "}") || c.p != c.end)
        goto none;
    PyObject *pt = PyLong_FromLongLong(t);
    if (pt == NULL)
        goto fail;
    if (is_tick) {
        PyObject *a[2] = {pt, link};
        result = PyObject_Vectorcall(tick_cls, a, 2, NULL);
    } else {
        PyObject *a[9] = {pt, raw, bt, PyTuple_New(0), ch, link, Py_None, Py_None, Py_False};
        if (a[3] != NULL)
            result = PyObject_Vectorcall(chunk_cls, a, 9, NULL);
        Py_XDECREF(a[3]);
    }
    Py_DECREF(pt);
    goto fail;  /* result set (or an error): release the parts */
none:
    if (PyErr_Occurred())
        goto fail;
    result = Py_NewRef(Py_None);
fail:
    Py_XDECREF(raw);
    Py_XDECREF(bt);
    Py_XDECREF(ch);
    Py_XDECREF(link);
    PyBuffer_Release(&b);
    return result;
}


/* ------------------------------------------------------------------ table rows (formats/rows.py, csvexport.py) */

static PyObject *s_raw, *s_value, *s_address, *s_name, *s_id, *s_text, *s_unit;

/* d.get(key) as a borrowed reference (Py_None when absent); NULL with an error set */
static PyObject *dget(PyObject *d, PyObject *key)
{
    PyObject *v = PyDict_GetItemWithError(d, key);
    if (v == NULL && !PyErr_Occurred())
        return Py_None;
    return v;
}

/* rows.py point_rows' loop: point_rows(points, head, link, text) -> [row, ...], or None where a point is not a
   plain dict (the Python loop reads those).  `text` is rows._text, asked for a value that is no str or number. */
static PyObject *point_rows(PyObject *self, PyObject *args)
{
    PyObject *pts, *head, *link, *text_fn;
    if (!PyArg_ParseTuple(args, "O!O!OO", &PyList_Type, &pts, &PyTuple_Type, &head, &link, &text_fn))
        return NULL;
    Py_ssize_t n = PyList_GET_SIZE(pts), nh = PyTuple_GET_SIZE(head);
    for (Py_ssize_t k = 0; k < n; k++)
        if (!PyDict_CheckExact(PyList_GET_ITEM(pts, k)))
            Py_RETURN_NONE;
    PyObject *out = PyList_New(n);
    if (out == NULL)
        return NULL;
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *p = PyList_GET_ITEM(pts, k);
        PyObject *raw = dget(p, s_raw), *v = dget(p, s_value), *addr = dget(p, s_address), *name = dget(p, s_name),
                 *id = dget(p, s_id), *text = dget(p, s_text), *unit = dget(p, s_unit);
        if (!raw || !v || !addr || !name || !id || !text || !unit)
            goto fail;
        int t;
        if ((t = PyObject_IsTrue(name)) < 0)
            goto fail;
        if (!t)
            name = s_empty;
        if ((t = PyObject_IsTrue(id)) < 0)
            goto fail;
        if (!t)
            id = s_empty;
        PyObject *raw_out = Py_None;
        if (PyLong_CheckExact(raw)) {
            int overflow;
            PyLong_AsLongLongAndOverflow(raw, &overflow);
            if (PyErr_Occurred())
                goto fail;
            if (overflow <= 0)
                raw_out = raw;  /* raw <= 2**63 - 1 */
        }
        PyObject *num;
        if (PyLong_CheckExact(v) || PyFloat_CheckExact(v) || PyBool_Check(v)) {
            num = PyNumber_Float(v);
            if (num == NULL)
                goto fail;
        } else
            num = Py_NewRef(Py_None);
        PyObject *txt;
        if ((t = PyObject_IsTrue(text)) < 0) {
            Py_DECREF(num);
            goto fail;
        }
        if (t)
            txt = Py_NewRef(text);
        else if (v == Py_None)
            txt = Py_NewRef(Py_None);
        else if (PyUnicode_Check(v))
            txt = Py_NewRef(v);
        else if (PyLong_Check(v) || PyFloat_Check(v))  /* bool is an int */
            txt = PyObject_Str(v);
        else
            txt = PyObject_CallOneArg(text_fn, v);
        if (txt == NULL) {
            Py_DECREF(num);
            goto fail;
        }
        PyObject *row = PyTuple_New(nh + 8);
        if (row == NULL) {
            Py_DECREF(num);
            Py_DECREF(txt);
            goto fail;
        }
        for (Py_ssize_t j = 0; j < nh; j++)
            PyTuple_SET_ITEM(row, j, Py_NewRef(PyTuple_GET_ITEM(head, j)));
        PyTuple_SET_ITEM(row, nh, Py_NewRef(addr));
        PyTuple_SET_ITEM(row, nh + 1, Py_NewRef(name));
        PyTuple_SET_ITEM(row, nh + 2, Py_NewRef(id));
        PyTuple_SET_ITEM(row, nh + 3, Py_NewRef(raw_out));
        PyTuple_SET_ITEM(row, nh + 4, num);
        PyTuple_SET_ITEM(row, nh + 5, txt);
        PyTuple_SET_ITEM(row, nh + 6, Py_NewRef(unit));
        PyTuple_SET_ITEM(row, nh + 7, Py_NewRef(link));
        PyList_SET_ITEM(out, k, row);
    }
    return out;
fail:
    Py_DECREF(out);  /* a list with NULL items is freed as one */
    return NULL;
}

typedef struct {
    char *p;
    size_t n, cap;
} obuf_t;

static int put(obuf_t *b, const char *s, size_t n)
{
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->n + n)
            cap *= 2;
        char *q = PyMem_Realloc(b->p, cap);
        if (q == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->n, s, n);
    b->n += n;
    return 0;
}

enum { K_STR, K_INT, K_FLOAT, K_BOOL };

/* csvexport.py csv_text: csv_text(rows, kinds, float_text) -> bytes, or None where a cell is not of its
   column's plain type (a str column's non-str, an int column's bool ...: the Python code writes those).
   kinds: "str" | "int" | "float" | "bool" a column; float_text: csvexport.float_text, asked for the floats
   whose repr is not Arrow's text (an exponent, inf/nan, more than 10 digits before the point). */
static PyObject *csv_text(PyObject *self, PyObject *args)
{
    PyObject *rows, *kinds_t, *float_text;
    if (!PyArg_ParseTuple(args, "O!O!O", &PyList_Type, &rows, &PyTuple_Type, &kinds_t, &float_text))
        return NULL;
    Py_ssize_t nk = PyTuple_GET_SIZE(kinds_t), nr = PyList_GET_SIZE(rows);
    if (nk == 0 || nk > 64)
        Py_RETURN_NONE;
    int kinds[64];
    for (Py_ssize_t j = 0; j < nk; j++) {
        const char *k = PyUnicode_AsUTF8(PyTuple_GET_ITEM(kinds_t, j));
        if (k == NULL)
            return NULL;
        kinds[j] = !strcmp(k, "str") ? K_STR : !strcmp(k, "int") ? K_INT : !strcmp(k, "float") ? K_FLOAT : K_BOOL;
    }
    if (nr == 0)
        return PyBytes_FromStringAndSize("\n", 1);  /* no rows: one empty line, as the Python join gives */
    obuf_t b = {NULL, 0, 0};
    char num[64];
    for (Py_ssize_t i = 0; i < nr; i++) {
        PyObject *row = PyList_GET_ITEM(rows, i);
        if (!PyTuple_CheckExact(row) || PyTuple_GET_SIZE(row) != nk)
            goto none;
        if (i && put(&b, "\n", 1) < 0)
            goto fail;
        for (Py_ssize_t j = 0; j < nk; j++) {
            PyObject *v = PyTuple_GET_ITEM(row, j);
            if (j && put(&b, ",", 1) < 0)
                goto fail;
            if (v == Py_None)
                continue;
            switch (kinds[j]) {
            case K_STR: {
                if (!PyUnicode_CheckExact(v))
                    goto none;
                Py_ssize_t n;
                const char *s = PyUnicode_AsUTF8AndSize(v, &n);
                if (s == NULL) {
                    PyErr_Clear();  /* a lone surrogate: the Python code raises it */
                    goto none;
                }
                if (put(&b, "\"", 1) < 0)
                    goto fail;
                const char *q;
                while ((q = memchr(s, '"', (size_t)n)) != NULL) {
                    if (put(&b, s, (size_t)(q - s) + 1) < 0 || put(&b, "\"", 1) < 0)
                        goto fail;
                    n -= q - s + 1;
                    s = q + 1;
                }
                if (put(&b, s, (size_t)n) < 0 || put(&b, "\"", 1) < 0)
                    goto fail;
                break;
            }
            case K_INT: {
                if (!PyLong_CheckExact(v))
                    goto none;
                int overflow;
                long long x = PyLong_AsLongLongAndOverflow(v, &overflow);
                if (overflow || (x == -1 && PyErr_Occurred())) {
                    PyErr_Clear();
                    goto none;
                }
                int n = snprintf(num, sizeof num, "%lld", x);
                if (put(&b, num, (size_t)n) < 0)
                    goto fail;
                break;
            }
            case K_FLOAT: {
                if (!PyFloat_CheckExact(v))
                    goto none;
                char *r = PyOS_double_to_string(PyFloat_AS_DOUBLE(v), 'r', 0, Py_DTSF_ADD_DOT_0, NULL);
                if (r == NULL)
                    goto fail;
                size_t n = strlen(r);
                const char *dot = strchr(r, '.');
                if (strchr(r, 'e') || strchr(r, 'n') || dot == NULL || dot == r || dot - r > 10) {
                    PyMem_Free(r);
                    PyObject *t = PyObject_CallOneArg(float_text, v);
                    if (t == NULL)
                        goto fail;
                    Py_ssize_t tn;
                    const char *ts = PyUnicode_AsUTF8AndSize(t, &tn);
                    int bad = ts == NULL || put(&b, ts, (size_t)tn) < 0;
                    Py_DECREF(t);
                    if (bad)
                        goto fail;
                    break;
                }
                if (n >= 2 && r[n - 2] == '.' && r[n - 1] == '0')
                    n -= 2;
                int bad = put(&b, r, n) < 0;
                PyMem_Free(r);
                if (bad)
                    goto fail;
                break;
            }
            default: {
                int t = PyObject_IsTrue(v);
                if (t < 0)
                    goto fail;
                if (put(&b, t ? "true" : "false", t ? 4 : 5) < 0)
                    goto fail;
            }
            }
        }
    }
    if (put(&b, "\n", 1) < 0)
        goto fail;
    PyObject *out = PyBytes_FromStringAndSize(b.p, (Py_ssize_t)b.n);
    PyMem_Free(b.p);
    return out;
none:
    PyMem_Free(b.p);
    if (PyErr_Occurred())
        return NULL;
    Py_RETURN_NONE;
fail:
    PyMem_Free(b.p);
    return NULL;
}


/* ------------------------------------------------------------------ text lines (formats/text.py) */

static PyObject *s_annotations, *s_time_source, *s_none, *s_protocol, *s_noise, *s_role, *s_pair, *s_latency_ms,
    *s_de_on_ns, *s_de_off_ns, *s_function, *s_unit_attr, *s_crc_ok, *s_model, *s_generic, *s_summary, *s_t_ns_f;

/* a str attribute's UTF-8, or NULL (no error left set) where it is not a plain str */
static const char *utf8_of(PyObject *v, Py_ssize_t *n)
{
    if (!PyUnicode_CheckExact(v))
        return NULL;
    const char *s = PyUnicode_AsUTF8AndSize(v, n);
    if (s == NULL)
        PyErr_Clear();
    return s;
}

/* text.py frame_line for the common frame (a time, no annotations, no link column, no DE, unit and function
   in 0..255): frame_line(frame, t0_ns) -> str, or None where frame_line_py writes it. */
static PyObject *frame_line(PyObject *self, PyObject *args)
{
    PyObject *f, *t0o;
    if (!PyArg_ParseTuple(args, "OO", &f, &t0o))
        return NULL;
    PyObject *v[14] = {NULL};
    enum { ANN, TS, PROTO, ROLE, PAIR, LAT, DE_ON, DE_OFF, FC, UNIT, CRC, MODEL, SUMMARY, TNS };
    PyObject *names[14] = {s_annotations, s_time_source, s_protocol, s_role, s_pair, s_latency_ms, s_de_on_ns,
                           s_de_off_ns, s_function, s_unit_attr, s_crc_ok, s_model, s_summary, s_t_ns_f};
    PyObject *result = NULL;
    char buf[512];
    char *out = NULL;
    for (int k = 0; k < 14; k++)
        if ((v[k] = PyObject_GetAttr(f, names[k])) == NULL)
            goto done;
    if (!PyList_CheckExact(v[ANN]) || PyList_GET_SIZE(v[ANN]) != 0)
        goto none;
    if (!PyUnicode_CheckExact(v[TS]) || PyUnicode_Compare(v[TS], s_none) == 0)
        goto none;
    if (!PyUnicode_CheckExact(v[PROTO]) || PyUnicode_Compare(v[PROTO], s_noise) == 0)
        goto none;
    if (v[DE_ON] != Py_None || v[DE_OFF] != Py_None)
        goto none;
    if (!PyLong_CheckExact(v[TNS]) || !PyLong_CheckExact(t0o))
        goto none;
    int ovf;
    long long tns = PyLong_AsLongLongAndOverflow(v[TNS], &ovf);
    if (ovf)
        goto none;
    long long t0 = PyLong_AsLongLongAndOverflow(t0o, &ovf);
    if (ovf)
        goto none;
    long long dt;
    if (__builtin_sub_overflow(tns, t0, &dt))
        goto none;
    const char *dir;
    if (!PyUnicode_CheckExact(v[ROLE]))
        goto none;
    if (PyUnicode_CompareWithASCIIString(v[ROLE], "request") == 0)
        dir = "->REQ";
    else if (PyUnicode_CompareWithASCIIString(v[ROLE], "response") == 0)
        dir = "<-RSP";
    else
        dir = "<-???";
    char pair[32] = "";
    if (v[PAIR] != Py_None) {
        if (!PyLong_CheckExact(v[PAIR]))
            goto none;
        long long x = PyLong_AsLongLongAndOverflow(v[PAIR], &ovf);
        if (ovf)
            goto none;
        snprintf(pair, sizeof pair, " #%lld", x);
    }
    char lat[64] = "";
    if (v[LAT] != Py_None) {
        if (!PyFloat_CheckExact(v[LAT]))
            goto none;
        char *r = PyOS_double_to_string(PyFloat_AS_DOUBLE(v[LAT]), 'f', 1, 0, NULL);
        if (r == NULL)
            goto done;
        if (strlen(r) > 40) {
            PyMem_Free(r);
            goto none;
        }
        snprintf(lat, sizeof lat, " %6s" "ms", r);
        PyMem_Free(r);
    }
    char fc[4];
    if (v[FC] == Py_None)
        strcpy(fc, "--");
    else {
        if (!PyLong_CheckExact(v[FC]))
            goto none;
        long x = PyLong_AsLong(v[FC]);
        if (x < 0 || x > 255) {
            PyErr_Clear();
            goto none;
        }
        snprintf(fc, sizeof fc, "%02X", (unsigned)x);
    }
    char unit[8];
    if (v[UNIT] == Py_None)
        strcpy(unit, "?  ");
    else {
        if (!PyLong_CheckExact(v[UNIT]))
            goto none;
        long x = PyLong_AsLong(v[UNIT]);
        if (x < 0 || x > 255) {
            PyErr_Clear();
            goto none;
        }
        snprintf(unit, sizeof unit, "%-3ld", x);
    }
    int crc = PyObject_IsTrue(v[CRC]);
    if (crc < 0)
        goto done;
    const char *model = "";
    Py_ssize_t nmodel = 0;
    if (v[MODEL] != Py_None) {
        model = utf8_of(v[MODEL], &nmodel);
        if (model == NULL)
            goto none;
        if (nmodel == 7 && memcmp(model, "generic", 7) == 0)
            nmodel = 0;
    }
    Py_ssize_t nsum;
    const char *summary = utf8_of(v[SUMMARY], &nsum);
    if (summary == NULL)
        goto none;
    PyObject *idx = PyObject_GetAttr(f, s_index);
    if (idx == NULL)
        goto done;
    long long index = PyLong_CheckExact(idx) ? PyLong_AsLongLongAndOverflow(idx, &ovf) : (ovf = 1, 0);
    Py_DECREF(idx);
    if (ovf)
        goto none;
    char *t = PyOS_double_to_string((double)dt / 1e9, 'f', 6, 0, NULL);
    if (t == NULL)
        goto done;
    if (strlen(t) > 100) {
        PyMem_Free(t);
        goto none;
    }
    char head[256];
    int nh = snprintf(head, sizeof head, "%12s    %s u%s", t, dir, unit);
    PyMem_Free(t);
    char mid[160];
    int nm = snprintf(mid, sizeof mid, " fc%s%s #%lld%s%s  ", fc, crc ? "" : " CRC!", index, pair, lat);
    size_t total = (size_t)nh + (nmodel ? 1 + (size_t)nmodel : 0) + (size_t)nm + (size_t)nsum;
    out = total <= sizeof buf ? buf : PyMem_Malloc(total);
    if (out == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    char *w = out;
    memcpy(w, head, (size_t)nh);
    w += nh;
    if (nmodel) {
        *w++ = ' ';
        memcpy(w, model, (size_t)nmodel);
        w += nmodel;
    }
    memcpy(w, mid, (size_t)nm);
    w += nm;
    memcpy(w, summary, (size_t)nsum);
    w += nsum;
    result = PyUnicode_DecodeUTF8(out, w - out, NULL);
    goto done;
none:
    if (!PyErr_Occurred())
        result = Py_NewRef(Py_None);
done:
    if (out != NULL && out != buf)
        PyMem_Free(out);
    for (int k = 0; k < 14; k++)
        Py_XDECREF(v[k]);
    return result;
}

/* ------------------------------------------------------------------ analysis/linehealth.py LineHealthPy */

/* Health: LineHealthPy's window and counters (the reference, analysis/linehealth.py) as a C type;
   LineHealth subclasses it and builds the Change.  Times within +-2**61 ns, sizes within 2**40 and a
   badness of None, 0, 1 or 2 are kept here (every sum and share then exact in 64 bits and doubles);
   any other value hands the whole state to a LineHealthPy (self._hand_over()) that runs from then on. */
#define H_TIME_MAX (1LL << 61)
#define H_SIZE_MAX (1LL << 40)

typedef struct {
    PyObject_HEAD
    PyObject *link;
    PyObject *py;  /* the reference it handed over to, or NULL */
    long long window_ns, min_span_ns, min_frames, min_bytes;
    double broken_share, recovered_share;
    Py_ssize_t cap, head, len;  /* the ring: item i at (head + i) % cap */
    long long *t, *nb;
    signed char *bad;  /* -1: good */
    long long frames, nbytes, nbad, bad_bytes, kinds[3], warnings;
    int broken;
} Health;

static PyObject *s_change, *s_hand_over;

static int health_init(Health *self, PyObject *args, PyObject *kw)
{
    PyObject *link;
    Py_ssize_t cap;
    if (!PyArg_ParseTuple(args, "OLLnLLdd", &link, &self->window_ns, &self->min_span_ns, &cap, &self->min_frames,
                          &self->min_bytes, &self->broken_share, &self->recovered_share))
        return -1;
    if (cap < 1 || cap > 4096 || self->window_ns < 0 || self->window_ns > H_TIME_MAX || self->min_span_ns < 0
        || self->min_span_ns > H_TIME_MAX || self->min_frames < 1) {
        PyErr_SetString(PyExc_ValueError, "Health: a window LineHealthPy keeps");
        return -1;
    }
    PyMem_Free(self->t);
    PyMem_Free(self->nb);
    PyMem_Free(self->bad);
    self->t = PyMem_New(long long, cap);
    self->nb = PyMem_New(long long, cap);
    self->bad = PyMem_New(signed char, cap);
    if (!self->t || !self->nb || !self->bad) {
        PyErr_NoMemory();
        return -1;
    }
    Py_INCREF(link);
    Py_XSETREF(self->link, link);
    Py_CLEAR(self->py);
    self->cap = cap;
    self->head = self->len = 0;
    self->frames = self->nbytes = self->nbad = self->bad_bytes = self->warnings = 0;
    self->kinds[0] = self->kinds[1] = self->kinds[2] = 0;
    self->broken = 0;
    return 0;
}

static void health_dealloc(Health *self)
{
    PyObject_GC_UnTrack(self);
    Py_CLEAR(self->link);
    Py_CLEAR(self->py);
    PyMem_Free(self->t);
    PyMem_Free(self->nb);
    PyMem_Free(self->bad);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int health_traverse(Health *self, visitproc visit, void *arg)
{
    Py_VISIT(self->link);
    Py_VISIT(self->py);
    Py_VISIT(Py_TYPE(self));
    return 0;
}

static int health_clear(Health *self)
{
    Py_CLEAR(self->link);
    Py_CLEAR(self->py);
    return 0;
}

static void health_drop_first(Health *self)  /* _drop(win.popleft()) */
{
    Py_ssize_t i = self->head;
    self->frames--;
    self->nbytes -= self->nb[i];
    if (self->bad[i] >= 0) {
        self->nbad--;
        self->bad_bytes -= self->nb[i];
        self->kinds[(int)self->bad[i]]--;
    }
    self->head = (i + 1) % self->cap;
    self->len--;
}

static inline long long health_first_t(Health *self) { return self->t[self->head]; }
static inline long long health_last_t(Health *self) { return self->t[(self->head + self->len - 1) % self->cap]; }

static void health_expire(Health *self, long long t_ns)
{
    while (self->len && health_first_t(self) <= t_ns - self->window_ns)
        health_drop_first(self);
}

static int health_enough(Health *self)
{
    return self->frames >= self->min_frames && self->nbytes >= self->min_bytes
           && (health_last_t(self) - health_first_t(self) >= self->min_span_ns || self->len == self->cap);
}

/* the shares as the reference compares them: an int against a float times an int, exact below 2**53 */
static int health_most_bad(Health *self)
{
    return (double)self->nbad > self->broken_share * (double)self->frames
           && (double)self->bad_bytes > self->broken_share * (double)self->nbytes;
}

static int health_mostly_good(Health *self)
{
    return (double)self->nbad <= self->recovered_share * (double)self->frames
           && (double)self->bad_bytes <= self->recovered_share * (double)self->nbytes;
}

static PyObject *health_judge_c(Health *self)
{
    if (!self->broken) {
        if (!health_most_bad(self) || !health_enough(self))
            Py_RETURN_NONE;
        self->broken = 1;
        self->warnings++;
    } else {
        if (!health_mostly_good(self) || !health_enough(self))
            Py_RETURN_NONE;
        self->broken = 0;
    }
    return PyObject_CallMethodNoArgs((PyObject *)self, s_change);
}

/* the reference takes over: self._hand_over() builds it from window() and the counters */
static int health_hand_over(Health *self)
{
    PyObject *py = PyObject_CallMethodNoArgs((PyObject *)self, s_hand_over);
    if (py == NULL)
        return -1;
    Py_XSETREF(self->py, py);
    return 0;
}

/* an exact int within +-limit, else 0 (not one for this type: hand over) */
static int health_int(PyObject *o, long long limit, long long *out)
{
    int overflow;
    if (!PyLong_Check(o))
        return 0;
    *out = PyLong_AsLongLongAndOverflow(o, &overflow);
    if (overflow || (*out == -1 && PyErr_Occurred())) {
        PyErr_Clear();
        return 0;
    }
    return *out >= -limit && *out <= limit;
}

/* LineHealthPy.add on kept values (b: badness, -1 for None) */
static PyObject *health_push(Health *self, long long t, long long n, long long b)
{
    if (self->len == self->cap)
        health_drop_first(self);  /* the deque drops it on append */
    Py_ssize_t i = (self->head + self->len) % self->cap;
    self->t[i] = t;
    self->nb[i] = n;
    self->bad[i] = (signed char)b;
    self->len++;
    self->frames++;
    self->nbytes += n;
    if (b >= 0) {
        self->nbad++;
        self->bad_bytes += n;
        self->kinds[b]++;
    }
    if (health_first_t(self) <= t - self->window_ns)
        health_expire(self, t);
    return health_judge_c(self);
}

#define HEALTH_DELEGATE(name, ...)                                        \
    if (self->py != NULL)                                                 \
        return PyObject_CallMethod(self->py, name, __VA_ARGS__)

static PyObject *health_add(Health *self, PyObject *const *args, Py_ssize_t nargs)
{
    long long t, n, b = -1;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "add(t_ns, nbytes, bad)");
        return NULL;
    }
    if (self->py == NULL
        && !(health_int(args[0], H_TIME_MAX, &t) && health_int(args[1], H_SIZE_MAX, &n) && n >= 0
             && (args[2] == Py_None || (health_int(args[2], 2, &b) && b >= 0))))
        if (health_hand_over(self) < 0)
            return NULL;
    HEALTH_DELEGATE("add", "OOO", args[0], args[1], args[2]);
    return health_push(self, t, n, b);
}

static PyObject *health_advance(Health *self, PyObject *arg)
{
    long long t;
    if (self->py == NULL && !health_int(arg, H_TIME_MAX, &t) && health_hand_over(self) < 0)
        return NULL;
    HEALTH_DELEGATE("advance", "O", arg);
    health_expire(self, t);
    Py_RETURN_NONE;
}

static PyObject *health_judge(Health *self, PyObject *unused)
{
    HEALTH_DELEGATE("judge", NULL);
    return health_judge_c(self);
}

static PyObject *health_enough_m(Health *self, PyObject *unused)
{
    HEALTH_DELEGATE("enough", NULL);
    return PyBool_FromLong(health_enough(self));  /* frames >= min_frames >= 1 first: the window is not empty */
}

static PyObject *health_most_bad_m(Health *self, PyObject *unused)
{
    HEALTH_DELEGATE("most_bad", NULL);
    return PyBool_FromLong(health_most_bad(self));
}

static PyObject *health_mostly_good_m(Health *self, PyObject *unused)
{
    HEALTH_DELEGATE("mostly_good", NULL);
    return PyBool_FromLong(health_mostly_good(self));
}

static PyObject *health_window(Health *self, PyObject *unused)
{
    HEALTH_DELEGATE("window", NULL);
    PyObject *out = PyList_New(self->len);
    if (out == NULL)
        return NULL;
    for (Py_ssize_t k = 0; k < self->len; k++) {
        Py_ssize_t i = (self->head + k) % self->cap;
        PyObject *item = self->bad[i] < 0 ? Py_BuildValue("(LLO)", self->t[i], self->nb[i], Py_None)
                                          : Py_BuildValue("(LLi)", self->t[i], self->nb[i], (int)self->bad[i]);
        if (item == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, k, item);
    }
    return out;
}

enum { H_FRAMES, H_NBYTES, H_BAD, H_BAD_BYTES, H_KINDS, H_BROKEN, H_WARNINGS, H_LINK, H_WINDOW_NS, H_MIN_SPAN_NS,
       };
static const char *const health_names[] = {"frames", "nbytes", "bad", "bad_bytes", "kinds", "broken", "warnings",
                                           "link", "window_ns", "min_span_ns"};

static PyObject *health_get(Health *self, void *closure)
{
    int which = (int)(intptr_t)closure;
    if (self->py != NULL)
        return PyObject_GetAttrString(self->py, health_names[which]);
    switch (which) {
    case H_FRAMES: return PyLong_FromLongLong(self->frames);
    case H_NBYTES: return PyLong_FromLongLong(self->nbytes);
    case H_BAD: return PyLong_FromLongLong(self->nbad);
    case H_BAD_BYTES: return PyLong_FromLongLong(self->bad_bytes);
    case H_KINDS: return Py_BuildValue("[LLL]", self->kinds[0], self->kinds[1], self->kinds[2]);
    case H_BROKEN: return PyBool_FromLong(self->broken);
    case H_WARNINGS: return PyLong_FromLongLong(self->warnings);
    case H_LINK: Py_INCREF(self->link); return self->link;
    case H_WINDOW_NS: return PyLong_FromLongLong(self->window_ns);
    default: return PyLong_FromLongLong(self->min_span_ns);
    }
}

static PyObject *health_handed_over(Health *self, void *unused)
{
    return PyBool_FromLong(self->py != NULL);
}

#define HGET(name, which) {name, (getter)health_get, NULL, NULL, (void *)(intptr_t)(which)}
static PyGetSetDef health_getset[] = {
    HGET("frames", H_FRAMES), HGET("nbytes", H_NBYTES), HGET("bad", H_BAD), HGET("bad_bytes", H_BAD_BYTES),
    HGET("kinds", H_KINDS), HGET("broken", H_BROKEN), HGET("warnings", H_WARNINGS), HGET("link", H_LINK),
    HGET("window_ns", H_WINDOW_NS), HGET("min_span_ns", H_MIN_SPAN_NS),
    {"handed_over", (getter)health_handed_over, NULL, "Did unusual input hand it to LineHealthPy?", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyMethodDef health_methods[] = {
    {"add", (PyCFunction)(void (*)(void))health_add, METH_FASTCALL, "LineHealthPy.add(t_ns, nbytes, bad)."},
    {"advance", (PyCFunction)health_advance, METH_O, "LineHealthPy.advance(t_ns)."},
    {"judge", (PyCFunction)health_judge, METH_NOARGS, "LineHealthPy.judge()."},
    {"enough", (PyCFunction)health_enough_m, METH_NOARGS, "LineHealthPy.enough()."},
    {"most_bad", (PyCFunction)health_most_bad_m, METH_NOARGS, "LineHealthPy.most_bad()."},
    {"mostly_good", (PyCFunction)health_mostly_good_m, METH_NOARGS, "LineHealthPy.mostly_good()."},
    {"window", (PyCFunction)health_window, METH_NOARGS, "The window's (t_ns, nbytes, bad), oldest first."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject HealthType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "sniffer._hot.Health",
    .tp_doc = "LineHealthPy's window and counters (analysis/linehealth.py); subclassed by LineHealth.",
    .tp_basicsize = sizeof(Health),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE | Py_TPFLAGS_HAVE_GC,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)health_init,
    .tp_dealloc = (destructor)health_dealloc,
    .tp_traverse = (traverseproc)health_traverse,
    .tp_clear = (inquiry)health_clear,
    .tp_methods = health_methods,
    .tp_getset = health_getset,
};

/* LineWarning.frame_py: badness(f) and LineWatch.add for a frame of a link whose Health runs in C; the
   Change or None, or NotImplemented where the Python code decides (a new link, a handed-over window, a
   frame of odd types).  badness: noise 2; a CRC neither False nor None good; a UART code 1; CRC False 0. */
static PyObject *s_link, *s_code;

static PyObject *health_frame(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "health_frame(lines, frame, uart_codes)");
        return NULL;
    }
    PyObject *lines = args[0], *f = args[1], *uart = args[2], *link, *h, *v;
    long long t, n, b = -1;
    if (!PyDict_CheckExact(lines) || !PyFrozenSet_CheckExact(uart))
        Py_RETURN_NOTIMPLEMENTED;
    if ((link = PyObject_GetAttr(f, s_link)) == NULL)
        return NULL;
    int truth = PyUnicode_CheckExact(link) ? PyUnicode_GET_LENGTH(link) != 0 : -2;
    if (truth == 0 || link == Py_None) {  /* f.link or "" */
        Py_SETREF(link, Py_NewRef(s_empty));
        truth = 1;
    }
    if (truth < 0) {
        Py_DECREF(link);
        Py_RETURN_NOTIMPLEMENTED;
    }
    h = PyDict_GetItemWithError(lines, link);  /* borrowed */
    Py_DECREF(link);
    if (h == NULL) {
        if (PyErr_Occurred())
            return NULL;
        Py_RETURN_NOTIMPLEMENTED;
    }
    if (!PyObject_TypeCheck(h, &HealthType) || ((Health *)h)->py != NULL)
        Py_RETURN_NOTIMPLEMENTED;
    if ((v = PyObject_GetAttr(f, s_t_ns)) == NULL)
        return NULL;
    int ok = health_int(v, H_TIME_MAX, &t);
    Py_DECREF(v);
    if (!ok)
        Py_RETURN_NOTIMPLEMENTED;
    if ((v = PyObject_GetAttr(f, s_raw)) == NULL)
        return NULL;
    ok = PyBytes_CheckExact(v);
    n = ok ? PyBytes_GET_SIZE(v) : 0;
    Py_DECREF(v);
    if (!ok || n > H_SIZE_MAX)
        Py_RETURN_NOTIMPLEMENTED;
    if ((v = PyObject_GetAttr(f, s_protocol)) == NULL)
        return NULL;
    ok = PyUnicode_CheckExact(v);
    int noise = ok && PyUnicode_Compare(v, s_noise) == 0;
    Py_DECREF(v);
    if (!ok)
        Py_RETURN_NOTIMPLEMENTED;
    if (noise)
        b = 2;
    else {
        PyObject *crc = PyObject_GetAttr(f, s_crc_ok);
        if (crc == NULL)
            return NULL;
        if (crc == Py_False || crc == Py_None) {  /* else a good CRC: no UART error either */
            PyObject *anns = PyObject_GetAttr(f, s_annotations);
            if (anns == NULL || !PyList_CheckExact(anns)) {
                Py_DECREF(crc);
                if (anns == NULL)
                    return NULL;
                Py_DECREF(anns);
                Py_RETURN_NOTIMPLEMENTED;
            }
            for (Py_ssize_t i = 0; i < PyList_GET_SIZE(anns) && b < 0; i++) {
                PyObject *code = PyObject_GetAttr(PyList_GET_ITEM(anns, i), s_code);
                int in = code == NULL ? -1 : PySet_Contains(uart, code);
                Py_XDECREF(code);
                if (in < 0) {
                    Py_DECREF(anns);
                    Py_DECREF(crc);
                    return NULL;
                }
                if (in)
                    b = 1;
            }
            Py_DECREF(anns);
            if (b < 0 && crc == Py_False)
                b = 0;
        }
        Py_DECREF(crc);
    }
    return health_push((Health *)h, t, n, b);
}

/* ------------------------------------------------------------------ decoders/generic/decoder.py decode_py */

/* GenericModbus.decode_py for the plain generic decoder (no model) on the traffic of nearly every line:
   0x01-0x04 requests, 0x03/0x04 responses, 0x06 both ways, 0x10 both ways, with the register-shadow
   writes (UnitState.commit) they do.  Every case that would annotate (an odd byte count, a quantity out
   of range, no request, a CRC-bad frame's read), every other function, and a shadow that is not a plain
   dict (sniffer.parallel's Overlay) returns NotImplemented before anything is changed: decode_py decides
   it.  ctx: (RESPONSE, RegisterBlock, UnitState, space by function (256), most quantity by function (256)). */
static PyObject *s_writes, *s_points_slot, *s_tables;

static int gen_commit(PyObject *f, PyObject *d, PyObject *space, long start, PyObject *values)
{
    Py_ssize_t k = PyList_GET_SIZE(values);
    for (Py_ssize_t i = 0; i < k; i++) {
        PyObject *key = PyLong_FromLong(start + (long)i);
        if (key == NULL || PyDict_SetItem(d, key, PyList_GET_ITEM(values, i)) < 0) {
            Py_XDECREF(key);
            return -1;
        }
        Py_DECREF(key);
    }
    PyObject *writes = PyObject_GetAttr(f, s_writes);
    if (writes == NULL)
        return -1;
    PyObject *w = Py_BuildValue("[OlO]", space, start, values);
    int r = w == NULL ? -1 : PyList_Append(writes, w);
    Py_XDECREF(w);
    Py_DECREF(writes);
    return r;
}

static PyObject *gen_words(const unsigned char *p, Py_ssize_t k)
{
    PyObject *out = PyList_New(k);
    if (out == NULL)
        return NULL;
    for (Py_ssize_t i = 0; i < k; i++) {
        PyObject *v = PyLong_FromLong((p[2 * i] << 8) | p[2 * i + 1]);
        if (v == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, i, v);
    }
    return out;
}

/* the shadow dict of `space`, or NULL with no error (not a plain dict: decode_py) */
static PyObject *gen_table(PyObject *state, PyObject *space, int *err)
{
    PyObject *tables = PyObject_GetAttr(state, s_tables), *d;
    *err = tables == NULL;
    if (tables == NULL || !PyDict_CheckExact(tables)) {
        Py_XDECREF(tables);
        return NULL;
    }
    d = PyDict_GetItemWithError(tables, space);
    *err = d == NULL && PyErr_Occurred();
    Py_DECREF(tables);
    return d != NULL && PyDict_CheckExact(d) ? d : NULL;  /* borrowed: the state holds it */
}

/* a frame attribute that must be exact bytes (NULL with no error: not bytes) */
static PyObject *gen_bytes(PyObject *o, int *err)
{
    PyObject *b = PyObject_GetAttr(o, s_adu);
    *err = b == NULL;
    if (b != NULL && !PyBytes_CheckExact(b))
        Py_CLEAR(b);
    return b;
}

/* crc_ok as 1 (True), 0 (False or None), -1 (anything else: decode_py) */
static int gen_crc(PyObject *o, int *err)
{
    PyObject *c = PyObject_GetAttr(o, s_crc_ok);
    *err = c == NULL;
    int r = c == Py_True ? 1 : (c == Py_False || c == Py_None) ? 0 : -1;
    Py_XDECREF(c);
    return r;
}

static int gen_set_block(PyObject *f, PyObject *block_cls, PyObject *space, long addr, PyObject *values, int offset,
                         const char *prefix)
{
    PyObject *block = PyObject_CallFunction(block_cls, "OlOi", space, addr, values, offset);
    if (block == NULL)
        return -1;
    PyObject *summary = PyObject_CallMethod(block, "summary", NULL);
    if (summary != NULL && prefix[0])
        Py_SETREF(summary, PyUnicode_FromFormat("%s%U", prefix, summary));
    int r = summary == NULL ? -1 : PyObject_SetAttr(f, s_points_slot, block);
    if (r == 0)
        r = PyObject_SetAttr(f, s_summary, summary);
    Py_XDECREF(summary);
    Py_DECREF(block);
    return r;
}

static PyObject *generic_fast(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4 || !PyTuple_Check(args[3]) || PyTuple_GET_SIZE(args[3]) != 5) {
        PyErr_SetString(PyExc_TypeError, "generic_fast(frame, request, state, ctx)");
        return NULL;
    }
    PyObject *f = args[0], *req = args[1], *state = args[2], *ctx = args[3];
    PyObject *response = PyTuple_GET_ITEM(ctx, 0), *block_cls = PyTuple_GET_ITEM(ctx, 1);
    PyObject *spaces = PyTuple_GET_ITEM(ctx, 3), *maxq = PyTuple_GET_ITEM(ctx, 4);
    PyObject *v, *adu = NULL, *radu = NULL, *values = NULL, *result = NULL, *d = NULL;
    int err = 0;
    if (!Py_IS_TYPE(state, (PyTypeObject *)PyTuple_GET_ITEM(ctx, 2)))
        Py_RETURN_NOTIMPLEMENTED;
    if ((v = PyObject_GetAttr(f, s_function)) == NULL)
        return NULL;
    long fc = PyLong_CheckExact(v) ? PyLong_AsLong(v) : -1;
    Py_DECREF(v);
    if (fc == -1 && PyErr_Occurred())
        PyErr_Clear();
    if (fc < 1 || fc > 0x10)
        Py_RETURN_NOTIMPLEMENTED;
    if ((v = PyObject_GetAttr(f, s_role)) == NULL)
        return NULL;
    int is_rsp = PyUnicode_CheckExact(v) ? PyUnicode_Compare(v, response) == 0 : -1;
    Py_DECREF(v);
    int crc = gen_crc(f, &err);
    if (err)
        return NULL;
    if (is_rsp < 0 || crc < 0)
        Py_RETURN_NOTIMPLEMENTED;
    if ((adu = gen_bytes(f, &err)) == NULL)
        return err ? NULL : Py_NewRef(Py_NotImplemented);
    const unsigned char *p = (const unsigned char *)PyBytes_AS_STRING(adu);
    Py_ssize_t n = PyBytes_GET_SIZE(adu);
    PyObject *space = PyTuple_GET_ITEM(spaces, fc), *hi_o = PyTuple_GET_ITEM(maxq, fc);
    long hi = hi_o == Py_None ? 0x10000 : PyLong_AsLong(hi_o);
    long unit0 = 0;
    if ((v = PyObject_GetAttr(f, s_unit_attr)) == NULL)
        goto done;
    unit0 = PyLong_CheckExact(v) && PyLong_AsLong(v) == 0;
    Py_DECREF(v);
    if (PyErr_Occurred())
        PyErr_Clear();  /* a unit past a C long: not 0 */
    if (n < 3 || space == Py_None)
        goto hand_back;
    long a = n >= 6 ? (p[2] << 8) | p[3] : 0, q = n >= 6 ? (p[4] << 8) | p[5] : 0;
    if (n < 6 && !((fc == 3 || fc == 4) && is_rsp))
        goto hand_back;  /* every other handler reads an address and a quantity or value */

    if (fc <= 4 && !is_rsp) {  /* _read_req */
        if (q < 1 || q > hi || a + q > 0x10000)
            goto hand_back;
        PyObject *s = PyUnicode_FromFormat("read %U %ld..%ld (%ld)", space, a, a + q - 1, q);
        if (s == NULL || PyObject_SetAttr(f, s_summary, s) < 0) {
            Py_XDECREF(s);
            goto done;
        }
        Py_DECREF(s);
        result = Py_NewRef(Py_None);
        goto done;
    }
    if (fc == 3 || fc == 4 || (fc == 0x10 && is_rsp)) {  /* both read the request: CRC-good, 6 bytes or more */
        if (req == Py_None || gen_crc(req, &err) != 1) {
            if (err)
                goto done;
            goto hand_back;
        }
        if ((radu = gen_bytes(req, &err)) == NULL) {
            if (err)
                goto done;
            goto hand_back;
        }
        if (PyBytes_GET_SIZE(radu) < 6)
            goto hand_back;
    }
    if (fc == 3 || fc == 4) {  /* _read_regs_rsp (is_rsp: the request side went above) */
        if (!is_rsp)
            goto hand_back;
        Py_ssize_t k = p[2] >> 1;
        const unsigned char *r = (const unsigned char *)PyBytes_AS_STRING(radu);
        long addr = (r[2] << 8) | r[3];
        if ((p[2] & 1) || n < 3 + 2 * k || addr + k > 0x10000 || !crc)
            goto hand_back;
        if (k && (d = gen_table(state, space, &err)) == NULL) {
            if (err)
                goto done;
            goto hand_back;
        }
        if ((values = gen_words(p + 3, k)) == NULL)
            goto done;
        if (k && gen_commit(f, d, space, addr, values) < 0)
            goto done;
        if (gen_set_block(f, block_cls, space, addr, values, 3, "") < 0)
            goto done;
        result = Py_NewRef(Py_None);
        goto done;
    }
    if (fc == 6) {  /* _write_single, the plain branch */
        int commit = crc && (is_rsp || unit0);
        if (commit && (d = gen_table(state, space, &err)) == NULL) {
            if (err)
                goto done;
            goto hand_back;
        }
        if (commit) {
            if ((values = gen_words(p + 4, 1)) == NULL || gen_commit(f, d, space, a, values) < 0)
                goto done;
        }
        PyObject *pts = Py_BuildValue("[{s:N,s:l,s:l,s:l,s:O,s:[ii]}]", "name",
                                      PyUnicode_FromFormat("%U[%ld]", space, a), "address", a, "raw", q, "value", q,
                                      "unit", Py_None, "span", 4, 6);
        if (pts == NULL)
            goto done;
        int r = PyObject_SetAttr(f, s_points_slot, pts);
        Py_DECREF(pts);
        if (r < 0)
            goto done;
        PyObject *s = PyUnicode_FromFormat("%s %U[%ld]=%ld", is_rsp ? "wrote" : "write", space, a, q);
        if (s == NULL || PyObject_SetAttr(f, s_summary, s) < 0) {
            Py_XDECREF(s);
            goto done;
        }
        Py_DECREF(s);
        result = Py_NewRef(Py_None);
        goto done;
    }
    if (fc == 0x10 && !is_rsp) {  /* _write_multi_req */
        if (n < 7)
            goto hand_back;
        Py_ssize_t k = p[6] >> 1;
        if (n < 7 + 2 * k || q < 1 || q > hi || a + k > 0x10000)
            goto hand_back;
        int commit = unit0 && crc && k;
        if (commit && (d = gen_table(state, space, &err)) == NULL) {
            if (err)
                goto done;
            goto hand_back;
        }
        if ((values = gen_words(p + 7, k)) == NULL)
            goto done;
        if (commit && gen_commit(f, d, space, a, values) < 0)
            goto done;
        if (gen_set_block(f, block_cls, space, a, values, 7, "write ") < 0)
            goto done;
        result = Py_NewRef(Py_None);
        goto done;
    }
    if (fc == 0x10) {  /* _write_multi_rsp: the request's values, confirmed by a response naming the same registers */
        if (q < 1 || q > hi || a + q > 0x10000)
            goto hand_back;
        const unsigned char *r = (const unsigned char *)PyBytes_AS_STRING(radu);
        Py_ssize_t rn = PyBytes_GET_SIZE(radu), k = rn >= 7 ? r[6] >> 1 : 0;
        long ra = (r[2] << 8) | r[3];
        if ((v = PyObject_GetAttr(req, s_function)) == NULL)
            goto done;
        int same_fc = PyLong_CheckExact(v) && PyLong_AsLong(v) == 0x10;
        Py_DECREF(v);
        if (!same_fc)
            goto hand_back;
        int commit = crc && memcmp(r + 2, p + 2, 4) == 0 && rn >= 7 && rn >= 7 + 2 * k && k && ra + k <= 0x10000;
        if (commit && (d = gen_table(state, space, &err)) == NULL) {
            if (err)
                goto done;
            goto hand_back;
        }
        if (commit && ((values = gen_words(r + 7, k)) == NULL || gen_commit(f, d, space, ra, values) < 0))
            goto done;
        PyObject *s = PyUnicode_FromFormat("wrote %U %ld..%ld (%ld)", space, a, a + q - 1, q);
        if (s == NULL || PyObject_SetAttr(f, s_summary, s) < 0) {
            Py_XDECREF(s);
            goto done;
        }
        Py_DECREF(s);
        result = Py_NewRef(Py_None);
        goto done;
    }
hand_back:
    result = Py_NewRef(Py_NotImplemented);
done:
    Py_XDECREF(adu);
    Py_XDECREF(radu);
    Py_XDECREF(values);
    return result;
}

/* ------------------------------------------------------------------ the module */

static PyMethodDef methods[] = {
    {"crc16", py_crc16, METH_O, "CRC-16/MODBUS of a bytes-like object (framing/crc.py crc16_raw)."},
    {"rtu_fast", rtu_fast, METH_VARARGS, "RtuFramer._fast's loop: rtu_fast(framer, out, Frame, roles) -> bool."},
    {"chunk_messages", chunk_messages, METH_VARARGS,
     "scan._walk_chunk's message loop: chunk_messages(data, pos, skipped, Message, out) -> pos."},
    {"decode_raw", decode_raw, METH_VARARGS,
     "format.decode_event for this sniffer's own messages: decode_raw(data, Chunk, Tick) -> event or None."},
    {"index_run", index_run, METH_O, "Scan._past_indexes' loop: index_run(buf) -> bytes of whole message indexes."},
    {"point_rows", point_rows, METH_VARARGS,
     "rows.point_rows' loop: point_rows(points, head, link, text) -> rows, or None for points of another kind."},
    {"csv_text", csv_text, METH_VARARGS,
     "csvexport.csv_text: csv_text(rows, kinds, float_text) -> bytes, or None for cells of another type."},
    {"frame_line", frame_line, METH_VARARGS,
     "text.frame_line for the common frame: frame_line(frame, t0_ns) -> str, or None for the others."},
    {"health_frame", (PyCFunction)(void (*)(void))health_frame, METH_FASTCALL,
     "LineWarning.frame_py's badness and LineWatch.add: health_frame(lines, frame, uart) -> Change, None or "
     "NotImplemented."},
    {"generic_fast", (PyCFunction)(void (*)(void))generic_fast, METH_FASTCALL,
     "GenericModbus.decode_py for the plain decoder's common frames: generic_fast(frame, request, state, ctx) -> "
     "None, or NotImplemented where decode_py decides."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "sniffer._hot", NULL, -1, methods};

#define INTERN(var, text) if ((var = PyUnicode_InternFromString(text)) == NULL) return NULL

PyMODINIT_FUNC PyInit__hot(void)
{
    crc_init();
    INTERN(s_buf, "buf");
    INTERN(s_base, "base");
    INTERN(s_pos, "pos");
    INTERN(s_avail, "_avail");
    INTERN(s_segs, "segs");
    INTERN(s_data, "data");
    INTERN(s_byte_t_ns, "byte_t_ns");
    INTERN(s_t_ns, "t_ns");
    INTERN(s_channel, "channel");
    INTERN(s_char_ns, "char_ns");
    INTERN(s_index, "index");
    INTERN(s_prev_frame_end_ns, "prev_frame_end_ns");
    INTERN(s_need, "_need");
    INTERN(s_is_boundary, "_is_boundary");
    INTERN(s_time_source, "time_source");
    INTERN(s_adu, "adu");
    INTERN(s_read, "read");
    INTERN(s_modbus_rtu, "modbus-rtu");
    INTERN(s_channel_id, "channel_id");
    INTERN(s_sequence, "sequence");
    INTERN(s_log_time, "log_time");
    INTERN(s_publish_time, "publish_time");
    INTERN(s_empty, "");
    INTERN(s_raw, "raw");
    INTERN(s_annotations, "annotations");
    INTERN(s_none, "none");
    INTERN(s_protocol, "protocol");
    INTERN(s_noise, "noise");
    INTERN(s_role, "role");
    INTERN(s_pair, "pair");
    INTERN(s_latency_ms, "latency_ms");
    INTERN(s_de_on_ns, "de_on_ns");
    INTERN(s_de_off_ns, "de_off_ns");
    INTERN(s_function, "function");
    INTERN(s_unit_attr, "unit");
    INTERN(s_crc_ok, "crc_ok");
    INTERN(s_model, "model");
    INTERN(s_generic, "generic");
    INTERN(s_summary, "summary");
    INTERN(s_t_ns_f, "t_ns");
    INTERN(s_value, "value");
    INTERN(s_address, "address");
    INTERN(s_name, "name");
    INTERN(s_id, "id");
    INTERN(s_text, "text");
    INTERN(s_unit, "unit");
    INTERN(s_change, "_change");
    INTERN(s_link, "link");
    INTERN(s_writes, "writes");
    INTERN(s_points_slot, "_points");
    INTERN(s_tables, "tables");
    INTERN(s_code, "code");
    INTERN(s_hand_over, "_hand_over");
    msg_kwnames = Py_BuildValue("(sssss)", "channel_id", "sequence", "log_time", "publish_time", "data");
    if (msg_kwnames == NULL)
        return NULL;
    if (PyType_Ready(&HealthType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL || PyModule_AddObjectRef(m, "Health", (PyObject *)&HealthType) < 0) {
        Py_XDECREF(m);
        return NULL;
    }
    return m;
}
