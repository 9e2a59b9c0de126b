"""A ToF frame's standard normal draws: SFC64 words -> float32 normals by the ziggurat method (compiled).

A pico flexx frame needs 344,736 float32 standard normals. NumPy's
``Generator.standard_normal`` makes them one call per draw through the bit
generator's function pointer, ~9-13 ns each (3-5 ms a frame, on the core that
the cast needs). Here the same kind of stream is made in one compiled loop:

- the words are NumPy's own SFC64 (Doty-Humphrey's small fast chaotic
  generator, 64-bit), seeded by NumPy (``np.random.SFC64(seed)``, through its
  SeedSequence) and then stepped here: the same words as ``random_raw``
  (tested);
- every 64-bit word gives two 32-bit draws, low half first;
- a draw is turned into a normal by Marsaglia and Tsang's ziggurat (2000)
  with 256 layers in float32: 8 bits pick the layer, 1 bit the sign, 23 bits
  the abscissa; inside the layer's inner rectangle (~99 % of draws) that is
  the value, otherwise the wedge test or the tail (Marsaglia's exponential
  method beyond r) takes uniforms (53 bits) from the next words of the stream,
  before the word's other half is used; a rejected draw starts over.

The draws depend on the seed only: n draws are the first n of any longer
run. They are not NumPy's ``standard_normal`` values (that is other code on
the same words); their distribution is tested (mean, variance, kurtosis,
Kolmogorov-Smirnov, the tail's share; ``tests/tof/test_normals.py``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from twinsense.compiled import jit

#: Layers of the ziggurat and the base layer's right edge r (Marsaglia and Tsang 2000, 256 layers).
LAYERS = 256
R = 3.6541528853610088
_BITS = 23  # abscissa bits of a 32-bit draw (8 for the layer, 1 for the sign)


def _tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, w, f): the ziggurat's tables for f(x) = exp(-x^2 / 2), layer i's right edge x_i.

    Every layer has the area v = r f(r) + int_r^inf f (the base: a rectangle of
    width r and the tail). Layer 0 is the base (its abscissa scale v / f(r)),
    layers 1..255 have their right edges x_1 < ... < x_255 = r from
    x_{i-1} = sqrt(-2 ln(v / x_i + f(x_i))). ``w[i]`` (float32) scales the 23-bit
    abscissa j to x = j w[i]; ``k[i]`` (uint32) is the bound below which x lies in
    the rectangle under the layer above (accepted at once); ``f[i]`` = f(x_i), f[0] = 1.
    """
    m = float(2 ** _BITS)
    v = R * math.exp(-0.5 * R * R) + math.sqrt(math.pi / 2.0) * float(special.erfc(R / math.sqrt(2.0)))
    x = np.zeros(LAYERS)
    x[LAYERS - 1] = R
    for i in range(LAYERS - 1, 1, -1):
        x[i - 1] = math.sqrt(-2.0 * math.log(v / x[i] + math.exp(-0.5 * x[i] * x[i])))
    q = v / math.exp(-0.5 * R * R)  # the base's abscissa scale: rectangle plus tail as one width
    k = np.zeros(LAYERS, np.uint32)
    w = np.zeros(LAYERS, np.float32)
    f = np.zeros(LAYERS, np.float64)
    k[0] = int(R / q * m)
    w[0] = q / m
    f[0] = 1.0
    for i in range(1, LAYERS):
        k[i] = int(x[i - 1] / x[i] * m) if i > 1 else 0  # layer 1 has no rectangle beneath (x_0 = 0)
        w[i] = x[i] / m
        f[i] = math.exp(-0.5 * x[i] * x[i])
    return k, w, f


_K, _W, _F = _tables()


@jit
def _sfc64(s):  # pragma: no cover
    """The next 64-bit word of the SFC64 state ``s`` = (a, b, c, counter) uint64 (stepped in place)."""
    a, b, c, w = s[0], s[1], s[2], s[3]
    out = a + b + w
    s[3] = w + np.uint64(1)
    s[0] = b ^ (b >> np.uint64(11))
    s[1] = c + (c << np.uint64(3))
    s[2] = ((c << np.uint64(24)) | (c >> np.uint64(40))) + out
    return out


@jit
def _words(s, out):  # pragma: no cover
    """``out`` (n,) uint64 filled with the next words of ``s`` (for tests against NumPy's SFC64)."""
    for i in range(out.shape[0]):
        out[i] = _sfc64(s)


@jit
def _uniform(s):  # pragma: no cover
    """A uniform float64 in (0, 1) from the top 53 bits of the next word (never 0: logs are taken)."""
    return (np.float64(_sfc64(s) >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


@jit
def _slow(u, s, f, w, r):  # pragma: no cover
    """The normal of draw ``u`` outside its layer's inner rectangle, or NaN if rejected (a new
    draw then starts over); the wedge test and the tail take uniforms from new words of ``s``."""
    i = u & np.uint32(0xFF)
    negative = (u & np.uint32(0x100)) != 0
    if i == 0:
        # The tail beyond r: Marsaglia's method with two exponentials.
        while True:
            e = -math.log(_uniform(s)) / r
            y = -math.log(_uniform(s))
            if y + y >= e * e:
                break
        return np.float32(-(r + e) if negative else r + e)
    # The wedge between layer i's rectangle and the curve: a uniform height in [f_i, f_{i-1}].
    x = np.float32(u >> np.uint32(9)) * w[i]
    xd = np.float64(x)
    if f[i] + _uniform(s) * (f[i - 1] - f[i]) < math.exp(-0.5 * xd * xd):
        return -x if negative else x
    return np.float32(np.nan)


@jit
def _fill(s, k, w, f, r, out):  # pragma: no cover
    """``out`` (n,) float32 filled with standard normals (see the module docstring); ``s`` stepped.

    Each word gives two draws, its low half first. The state is kept in locals
    on the fast path (a draw inside its layer's inner rectangle) and handed to
    :func:`_slow` through ``s`` for the rest (~1.2 % of draws), whose uniforms
    come from the next words, before the word's high half is used.
    """
    a, b, c, cnt = s[0], s[1], s[2], s[3]
    n = 0
    size = out.shape[0]
    while n < size:
        word = a + b + cnt
        cnt += np.uint64(1)
        a = b ^ (b >> np.uint64(11))
        b = c + (c << np.uint64(3))
        c = ((c << np.uint64(24)) | (c >> np.uint64(40))) + word
        for half in range(2):
            if n == size:
                break
            u = np.uint32(word & np.uint64(0xFFFFFFFF)) if half == 0 else np.uint32(word >> np.uint64(32))
            i = u & np.uint32(0xFF)
            j = u >> np.uint32(9)
            if j < k[i]:
                x = np.float32(j) * w[i]
                out[n] = -x if u & np.uint32(0x100) else x
                n += 1
                continue
            s[0], s[1], s[2], s[3] = a, b, c, cnt
            x = _slow(u, s, f, w, r)
            a, b, c, cnt = s[0], s[1], s[2], s[3]
            if x == x:
                out[n] = x
                n += 1
    s[0], s[1], s[2], s[3] = a, b, c, cnt


def seeded_state(seed: int) -> np.ndarray:
    """The (a, b, c, counter) uint64 state (4,) of NumPy's ``SFC64(seed)`` (seeded through SeedSequence)."""
    return np.array(np.random.SFC64(int(seed)).state["state"]["state"], np.uint64)


def standard_normals(seed: int, out: np.ndarray) -> np.ndarray:
    """``out`` (n,) float32 filled with the first n standard normals of the stream of ``seed``; returns it.

    Runs without the GIL (one compiled call).
    """
    _fill(seeded_state(seed), _K, _W, _F, R, out)
    return out


def sfc64_words(seed: int, n: int) -> np.ndarray:
    """The first n (n,) uint64 words of the stream of ``seed`` (what the normals are made of)."""
    out = np.empty(n, np.uint64)
    _words(seeded_state(seed), out)
    return out
