#!/usr/bin/python3
"""Golden for tests/test_nn_optim.c: torch.optim.Adam (without and with weight decay) and
torch.optim.SGD (momentum, +nesterov) for 3 steps on a small tensor with fixed gradients.
Run with Debian's python3-torch: /usr/bin/python3 make_optim_golden.py > optim_golden.txt
Format: one record per line, "name count v0 v1 ...", float32 values as %.9g."""
import torch

torch.manual_seed(1234)
N = 10
p0 = torch.randn(N)
grads = [torch.randn(N) for _ in range(3)]


def rec(name, t):
    v = t.detach().reshape(-1).tolist()
    print(name, len(v), " ".join("%.9g" % x for x in v))


rec("p0", p0)
for s, g in enumerate(grads):
    rec("g%d" % (s + 1), g)

configs = [
    ("adam", lambda p: torch.optim.Adam([p], lr=0.01, betas=(0.9, 0.999), eps=1e-8)),
    ("adam_wd", lambda p: torch.optim.Adam([p], lr=0.01, betas=(0.9, 0.999), eps=1e-8, weight_decay=0.1)),
    # a large eps makes its placement (after sqrt of the bias-corrected v) visible
    ("adam_eps", lambda p: torch.optim.Adam([p], lr=0.01, betas=(0.8, 0.99), eps=0.1, weight_decay=0.5)),
    ("sgd_mom", lambda p: torch.optim.SGD([p], lr=0.05, momentum=0.9, weight_decay=0.01)),
    ("sgd_nesterov", lambda p: torch.optim.SGD([p], lr=0.05, momentum=0.9, nesterov=True)),
    ("sgd_plain", lambda p: torch.optim.SGD([p], lr=0.05)),
]
for name, make in configs:
    p = p0.clone().requires_grad_(True)
    opt = make(p)
    for s, g in enumerate(grads):
        p.grad = g.clone()
        opt.step()
        rec("%s_p%d" % (name, s + 1), p)
    st = opt.state[p]
    if "exp_avg" in st:
        rec(name + "_m", st["exp_avg"])
        rec(name + "_v", st["exp_avg_sq"])
    if st.get("momentum_buffer") is not None:
        rec(name + "_buf", st["momentum_buffer"])
