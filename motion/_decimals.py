"""Exact, vectorised parsing of whitespace-separated decimal numbers in a byte buffer.

``np.array(text.split(), float)`` and ``np.loadtxt`` manage 40-55 MB/s on the project
machine because every number becomes a Python object. Here each token is read as 8-byte
windows (uint64) and decoded with SWAR arithmetic ("SIMD within a register"), so a token
costs a fixed few dozen numpy operations whatever its length and no Python object is made.

Tokens of the form [sign] digits [. digits] [e [sign] 1-3 digits] with at most 8 integer
and 15 significant digits and a decimal exponent within +-22 take that path. Their
mantissa m < 2**53 and 10**k are exact doubles, so m * 10**k or m / 10**k is correctly
rounded: the value is bit-identical to float() (Clinger's fast path). The rest (longer
numbers, nan, junk) are left to numpy's string conversion, which reports what is not a
number. Of 9.6 million values sampled from the Bandai files, 6 (such as 6.6e-19) took
the slow path.
"""

from __future__ import annotations

import numpy as np


def byte_windows(data) -> np.ndarray | None:
    """Every 8-byte window of ``data``, one per start byte, for parse_fast (None if data is tiny).

    As "S8" (alignment 1) numpy gathers them fast; the gathered copies are then read as
    little-endian uint64.
    """
    return np.ndarray((len(data) - 7,), "S8", buffer=data, strides=(1,)) if len(data) >= 32 else None


def token_bounds(chunk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # Every byte up to the space is a separator, as for str.split(); the rest are token bytes.
    token = chunk > 32
    edges = np.flatnonzero(token[1:] != token[:-1]) + 1
    if len(token) and token[0]:
        edges = np.concatenate(([0], edges))
    if len(token) and token[-1]:
        edges = np.append(edges, len(token))
    return edges[0::2], edges[1::2]


_U = np.uint64
_ZEROS, _HIGH_NIBBLES = _U(0x3030303030303030), _U(0xF0F0F0F0F0F0F0F0)
_LOW_BYTES, _HIGH_BITS = _U(0x0101010101010101), _U(0x8080808080808080)
# _KEEP_LAST[k] masks the last k characters of an 8-byte window read little-endian.
_KEEP_LAST = np.array([((1 << 8 * k) - 1) << (64 - 8 * k) for k in range(9)], np.uint64)
_POW10_INT = np.array([10**k for k in range(16)], np.uint64)
_POW10 = 10.0 ** np.arange(23)  # all exact doubles: the "Clinger fast path" is correctly rounded


def parse_fast(buf: np.ndarray, words: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of the tokens buf[starts:ends] and which of them were parsed exactly here.

    A token is [sign] int-digits [. frac-digits] [e [sign] exp-digits]. Each run of up to
    8 digits is read as one 8-byte window ending where the run ends, then checked and
    decoded with SWAR arithmetic on uint64, so a token costs a fixed few dozen vector
    operations whatever its length. The mantissa m (at most 15 digits, so < 2**53) and
    10**k (k <= 22) are exact doubles, so m * 10**k or m / 10**k is correctly rounded:
    the result is bit-identical to float(). Other tokens are left to parse_rest.
    """
    if words is None or not len(starts):
        return np.zeros(len(starts)), np.zeros(len(starts), bool)
    n = len(buf)
    # Windows reach 16 bytes before a token's end and 8 after its start; the few tokens
    # too near either end of the text (the last one, at most) take the slow path.
    inside = (starts >= 16) & (starts <= n - 8)
    st, en = np.where(inside, starts, 16), np.where(inside, ends, 17)
    length = en - st
    # Row 0: the first 8 characters, searched for the dot (one beyond them means more than
    # 8 integer digits: slow path). Row 1: the last 8, searched for the 'e' or 'E' (an
    # exponent has at most 3 digits), with the bytes before a short token blanked out.
    head, tail = ends_8 = _windows(words, np.stack([st, en - 8]))
    tail &= _KEEP_LAST[np.minimum(length, 8)]
    first = head & _U(0xFF)
    negative = first == ord("-")
    dot, e_at = _first_index(ends_8, _SEARCH_FOLD, _SEARCH_BYTES)
    mantissa_end = length - 8 + e_at  # e_at is 8 when there is no exponent
    has_dot = (dot < 8) & (dot < mantissa_end)  # 8: none among the first 8 characters
    int_end = np.where(has_dot, dot, mantissa_end)
    n_int = int_end - (negative | (first == ord("+")))
    n_frac = (mantissa_end - dot - 1) * has_dot
    ok = inside & (int_end <= 8) & (n_int + n_frac >= 1) & (n_int + n_frac <= 15)
    n_frac = np.minimum(n_frac, 15)
    # The integer digits end within the first 8 characters: shift them to the top of the
    # head window. The fraction digits end the token, so the tail window holds them,
    # except when an exponent follows.
    int_window = head << (_U(8) * (8 - int_end).astype(np.uint64))  # >= 64 gives 0
    exp = np.flatnonzero(e_at < 8)
    frac_window = tail
    if len(exp):
        frac_window = tail.copy()
        frac_window[exp] = _windows(words, st[exp] + mantissa_end[exp] - 8)
    (int_part, frac_part), digits_ok = _digit_run(np.stack([int_window, frac_window]), np.minimum(np.stack([n_int, n_frac]), 8))
    ok &= digits_ok[0] & digits_ok[1]
    long_frac = np.flatnonzero(n_frac > 8)
    if len(long_frac):  # 9-15 fraction digits: the leading ones sit in the window before
        lead, lead_ok = _digit_run(_windows(words, st[long_frac] + mantissa_end[long_frac] - 16), n_frac[long_frac] - 8)
        frac_part[long_frac] += lead * _U(10**8)
        ok[long_frac] &= lead_ok
    mantissa = (int_part * _POW10_INT[n_frac] + frac_part).astype(np.float64)
    value = mantissa / _POW10[n_frac]
    if len(exp):
        scale = _exponents(buf, ends_8[1, exp], st[exp] + mantissa_end[exp] + 1, en[exp], ok, exp) - n_frac[exp]
        ok[exp] &= np.abs(scale) <= 22
        scale = np.clip(scale, -22, 22)
        m = mantissa[exp]
        value[exp] = np.where(scale >= 0, m * _POW10[np.maximum(scale, 0)], m / _POW10[np.maximum(-scale, 0)])
    np.negative(value, out=value, where=negative)
    return value, ok


def _windows(words: np.ndarray, at: np.ndarray) -> np.ndarray:
    return words[at].view("<u8").reshape(at.shape)


def _exponents(buf, tails, starts, ends, ok, which) -> np.ndarray:
    """Exponent values of tokens whose exponent digits end their last-8-characters window."""
    sign = buf[starts]
    negative = sign == ord("-")
    count = ends - starts - (negative | (sign == ord("+")))
    value, digits_ok = _digit_run(tails, np.clip(count, 0, 3))
    ok[which] &= digits_ok & (count >= 1) & (count <= 3)
    value = value.astype(np.int64)
    return np.where(negative, -value, value)


def _digit_run(windows: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integer value of the last ``count`` (0-8) characters of each window, and whether all are digits."""
    keep = _KEEP_LAST[count]
    w = (windows & keep) | (_ZEROS & ~keep)  # characters before the run count as '0'
    ok = ((w & _HIGH_NIBBLES) == _ZEROS) & (((w + _U(0x0606060606060606)) & _HIGH_NIBBLES) == _ZEROS)
    w = w - _ZEROS
    w = (w * _U(10) + (w >> _U(8))) & _U(0x00FF00FF00FF00FF)  # pairs of digits
    w = (w * _U(100) + (w >> _U(16))) & _U(0x0000FFFF0000FFFF)  # groups of four
    return (w * _U(10000) + (w >> _U(32))) & _U(0xFFFFFFFF), ok


_SEARCH_FOLD = np.array([[0], [0x2020202020202020]], np.uint64)  # OR-ing 0x20 folds 'E' to 'e'
_SEARCH_BYTES = np.array([[ord(".") * 0x0101010101010101], [ord("e") * 0x0101010101010101]], np.uint64)


def _first_index(windows: np.ndarray, fold: np.ndarray, pattern: np.ndarray) -> np.ndarray:
    """Index (0-7, 8 if absent) of the first byte of each window that, OR-ed with fold, equals pattern's."""
    x = (windows | fold) ^ pattern
    zero = (x - _LOW_BYTES) & ~x & _HIGH_BITS  # flags zero bytes, exactly so for the lowest one
    return _bit_count((zero - _U(1)) & ~zero) >> 3  # trailing zero bits / 8; 64 / 8 = 8 when none


def _bit_count(x: np.ndarray) -> np.ndarray:
    if hasattr(np, "bitwise_count"):  # numpy >= 2.0
        return np.bitwise_count(x).astype(np.int64)
    x = x - ((x >> _U(1)) & _U(0x5555555555555555))
    x = (x & _U(0x3333333333333333)) + ((x >> _U(2)) & _U(0x3333333333333333))
    x = (x + (x >> _U(4))) & _U(0x0F0F0F0F0F0F0F0F)
    return ((x * _LOW_BYTES) >> _U(56)).astype(np.int64)


def parse_rest(data, starts: np.ndarray, ends: np.ndarray, values: np.ndarray, ok: np.ndarray) -> int | None:
    """Fill in the tokens parse_fast declined; return the index of the first that is not a finite number."""
    todo = np.flatnonzero(~ok)
    tokens = [bytes(data[s:e]) for s, e in zip(starts[todo].tolist(), ends[todo].tolist())]
    try:
        parsed = np.array(tokens, dtype=np.float64)
    except ValueError:  # find which one (this is the error path: one at a time is fine)
        return int(todo[next((i for i, t in enumerate(tokens) if not is_finite_number(t)), 0)])
    bad = np.flatnonzero(~np.isfinite(parsed))
    if len(bad):
        return int(todo[bad[0]])
    values[todo] = parsed
    return None


def is_finite_number(token: bytes) -> bool:
    try:
        return bool(np.isfinite(np.float64(token)))
    except ValueError:
        return False
