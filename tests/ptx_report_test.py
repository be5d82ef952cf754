"""Unit tests of scripts/device/ptx_report.py (run by tests/gpu_static_tools.sh): the sm_90
occupancy arithmetic against hand-worked cases, the ptxas -v and nvdisasm parsers and the inner-loop
finder on small listings written here, and every rule of --check, each of which must fire."""
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts", "device"))
import ptx_report as pr  # noqa: E402


class Occupancy(unittest.TestCase):
    def test_register_limited(self):
        # 65 registers: 2304 per warp (9 units of 256) -> 28 warps -> 14 groups of 2 warps = 28/64
        self.assertEqual(pr.occupancy(65, 12672, 64), (28 / 64, 14, "registers"))
        # 121 registers, 144 work-items = 5 warps: 3968 per warp -> 16 warps -> 3 groups = 15/64
        self.assertEqual(pr.occupancy(121, 24960, 144), (15 / 64, 3, "registers"))

    def test_warp_block_and_local_limits(self):
        self.assertEqual(pr.occupancy(32, 0, 256), (1.0, 8, "warps"))
        # 48 KiB + 1 KiB reserved per group: 233472 // 50176 = 4 groups of 8 warps
        self.assertEqual(pr.occupancy(16, 49152, 256), (0.5, 4, "local memory"))
        # one-warp groups: at most 32 resident groups
        self.assertEqual(pr.occupancy(16, 0, 32), (0.5, 32, "blocks"))
        self.assertEqual(pr.occupancy(16, 0, 2048)[0], 0.0)

    def test_same_occupancy_budget(self):
        self.assertEqual(pr.same_occupancy_regs(65, 12672, 64), 72)
        self.assertEqual(pr.same_occupancy_regs(16, 0, 256), 32)
        self.assertEqual(pr.occupancy(73, 12672, 64)[0] < pr.occupancy(72, 12672, 64)[0], True)


# ptxas -v's output; k_b's stack line with the 'ptxas  .' prefix that some builds of ptxas print
PTXAS_LOG = """ptxas info    : 0 bytes gmem
ptxas info    : Function properties for helper_fn
    16 bytes stack frame, 4 bytes spill stores, 4 bytes spill loads
ptxas info    : Compiling entry function 'k_a' for 'sm_90'
ptxas info    : Function properties for k_a
    0 bytes stack frame, 0 bytes spill stores, 0 bytes spill loads
ptxas info    : Used 40 registers, used 1 barriers, 4096 bytes smem, 380 bytes cmem[0]
ptxas info    : Compiling entry function 'k_b' for 'sm_90'
ptxas info    : Function properties for k_b
ptxas         .     96 bytes stack frame, 8 bytes spill stores, 12 bytes spill loads
ptxas info    : Used 255 registers, used 0 barriers, 96 bytes cumulative stack size
"""

# an outer loop (L1 .. the branch at 0x90) around an inner one (L2 .. 0x70), a second innermost
# loop (L3 .. 0xd0), the trap after EXIT that branches to itself
SASS = """//--------------------- .text.k_a --------------------------
.text.k_a:
        /*0000*/                   MOV R1, c[0x0][0x28] ;
.L_x_1:
        /*0010*/                   FFMA R2, R3, R4, R2 ;
.L_x_2:
        /*0020*/                   LDS R5, [R6] ;
        /*0030*/                   FFMA R2, R5, R4, R2 ;
        /*0040*/                   FFMA R7, R5, R4, R7 ;
        /*0050*/                   FFMA.FTZ R8, R5, R4, R8 ;
        /*0060*/                   NOP;
        /*0070*/               @P0 BRA `(.L_x_2) ;
        /*0080*/                   FFMA R9, R5, R4, R9 ;
        /*0090*/              @!P1 BRA `(.L_x_1) ;
.L_x_3:
        /*00a0*/                   LDG.E R10, desc[UR4][R12.64] ;
        /*00b0*/                   FFMA R2, R10, R4, R2 ;
        /*00c0*/                   IADD3 R12, R12, 0x4, RZ ;
        /*00d0*/               @P2 BRA `(.L_x_3) ;
        /*00e0*/                   EXIT ;
.L_x_4:
        /*00f0*/                   BRA `(.L_x_4);
//--------------------- .text.k_b --------------------------
.text.k_b:
        /*0000*/                   LDL R1, [R1+0x8] ;
        /*0010*/                   EXIT ;
"""


class Parsers(unittest.TestCase):
    def test_ptxas(self):
        k = pr.parse_ptxas(PTXAS_LOG)
        self.assertEqual(sorted(k), ["k_a", "k_b"])
        self.assertEqual(k["k_a"], {"regs": 40, "stack": 0, "spill_st": 0, "spill_ld": 0, "smem": 4096, "barriers": 1})
        self.assertEqual(k["k_b"], {"regs": 255, "stack": 96, "spill_st": 8, "spill_ld": 12, "smem": 0, "barriers": 0})

    def test_inner_loop(self):
        funcs = pr.parse_sass(SASS)
        insns, labels = funcs["k_a"]
        self.assertEqual(labels, {".L_x_1": 0x10, ".L_x_2": 0x20, ".L_x_3": 0xa0, ".L_x_4": 0xf0})
        m, a, b = pr.inner_loop(insns, labels)
        self.assertEqual((a, b), (0x20, 0x70))  # innermost with the most FFMA; the NOP not counted
        self.assertEqual((m["n"], m["ffma"], m["lds"]), (5, 3, 1))
        self.assertAlmostEqual(m["ffma_share"], 0.6)
        m, a, b = pr.inner_loop(*funcs["k_b"])
        self.assertEqual((a, b, m["n"], m["local"]), (None, None, 2, 1))  # no loop: the whole kernel


def row(prog, regs=32, stack=0, spill=0, smem=0):
    return {"program": prog, "regs": regs, "stack": stack, "spill_st": spill, "spill_ld": spill, "smem": smem}


class Rules(unittest.TestCase):
    def rules(self, text):
        with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
            f.write(text)
        try:
            return pr.read_rules(f.name)
        finally:
            os.unlink(f.name)

    def setUp(self):
        self.r = self.rules("# comment\nkernel spx_conv2d_x 64 72  # trailing\nstrict spx_conv2d_* spx_wino_*\n"
                            "waive spx_wino_t 144 transform scratch\n")
        self.rows = {"spx_conv2d_x": row("c"), "spx_wino_t": row("w", stack=144), "spx_other": row("o", stack=64)}

    def test_clean(self):
        self.assertEqual(pr.check(self.rows, self.r), [])

    def test_each_rule_fires(self):
        cases = [
            ("spx_conv2d_x", row("c", regs=73), "over its budget of 72"),
            ("spx_conv2d_x", row("c", spill=4), "spills"),
            ("spx_conv2d_x", row("c", stack=16), "16-byte stack frame"),
            ("spx_wino_t", row("w", stack=160), "(waived up to 144)"),
            ("spx_wino_t", row("w"), "no stack frame now"),
            ("spx_other", row("o", smem=49153), "over NVIDIA's 48 KiB"),
        ]
        for k, r, needle in cases:
            rows = dict(self.rows, **{k: r})
            bad = pr.check(rows, self.r)
            self.assertEqual(len(bad), 1, (k, bad))
            self.assertIn(needle, bad[0])

    def test_stale_rows_only_when_complete(self):
        rows = {"spx_other": row("o")}
        self.assertEqual(pr.check(rows, self.r, complete=False), [])
        bad = pr.check(rows, self.r, complete=True)
        self.assertEqual(len(bad), 2)
        self.assertTrue(any("kernel spx_conv2d_x: no analysed kernel" in b for b in bad))

    def test_malformed_line(self):
        with self.assertRaises(SystemExit) as e:
            self.rules("kernel spx_a 64\n")
        self.assertIn(":1: expected", str(e.exception))


if __name__ == "__main__":
    unittest.main()
