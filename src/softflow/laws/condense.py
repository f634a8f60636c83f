"""The static condensation's block inverses in one compiled pass
(:mod:`softflow.solve.condense`): X = B^-1 [I | A_er] of every condensed
group whose block B is triangular up to a permutation, by substitution.

The Python code did each group with NumPy operations vectorized over its
instances; where each actuator has a PV curve of its own, most groups hold
one instance (a 2 000-component water network: 454 of its 472 blocks), and
the operations' dispatch was the cost: 59 490 blocks inverted in its run's
127 factorizations, 0.64 s. Here a factorization's blocks are one call, with
the same arithmetic in the same order (bitwise the same X)."""
from __future__ import annotations

import numpy as np

from . import jit

#: the columns of ``blocks`` (one row a block)
J0, N, NPAT, XOFF, K, M, O0, O1 = range(8)
#: the columns of ``order`` (one row a pivot of a block's substitution)
E, A, R0, R1 = range(4)


@jit
def invert_blocks(raw, values, blocks, order, cells, which, pivot_min, ok):
    """X = B^-1 [I | A_er] of the blocks ``which`` (rows of ``blocks``), into
    ``values`` (block b's X, instance i, row a, column j at
    ``values[xoff + (i k + a)(k + m) + j]``) from the group's raw Jacobian
    values (instance i, pattern entry p at ``raw[j0 + i npat + p]``).

    ``blocks``: per block (j0, n, npat, xoff, k, m, o0, o1), its pivots the
    rows o0..o1 of ``order``: (e, a, r0, r1), equation e solved for own
    unknown a, the equation's entries the rows r0..r1 of ``cells``: (p, c),
    pattern entry p in column c of [B | A_er]. ``ok[w]``: whether block
    ``which[w]`` is regular, each pivot above ``pivot_min``
    (:data:`softflow.solve.condense.PIVOT_MIN`) times the largest entry of
    its row that multiplies a known unknown."""
    for w in range(which.size):
        b = which[w]
        j0, n, npat, xoff = blocks[b, J0], blocks[b, N], blocks[b, NPAT], blocks[b, XOFF]
        k, m = blocks[b, K], blocks[b, M]
        width = k + m
        acc = np.empty(width)
        regular = True
        for i in range(n):
            jrow = j0 + i * npat
            xrow = xoff + i * k * width
            for o in range(blocks[b, O0], blocks[b, O1]):
                e, a = order[o, E], order[o, A]
                acc[:] = 0.0
                acc[e] = 1.0
                piv = 0.0
                big = 0.0
                for r in range(order[o, R0], order[o, R1]):
                    p, c = cells[r, 0], cells[r, 1]
                    v = raw[jrow + p]
                    if c == a:
                        piv = v
                    elif c >= k:
                        acc[c] += v
                    else:
                        xc = xrow + c * width
                        for j in range(width):
                            acc[j] -= v * values[xc + j]
                        # np.maximum's: a NaN on either side is kept
                        av = abs(v)
                        if av > big or av != av:
                            big = av
                if not abs(piv) > pivot_min * big:
                    regular = False
                    break
                xa = xrow + a * width
                for j in range(width):
                    values[xa + j] = acc[j] / piv
            if not regular:
                break
        ok[w] = regular
