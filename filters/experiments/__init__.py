"""What every experiment shares, and the experiments that need nothing above `filters`.

* `.runner` -- seeded jobs run sequentially, in a process pool or on Ray (same results).
* `.stats` -- confidence intervals from `scipy.stats` (Wilson, Student-t, normal, paired bootstrap).
* `.report` -- Markdown tables, number formats, generated blocks in documents, figure files.
* `.cli` -- typed command lines from frozen dataclasses (tyro), with the runner's options.
* `.paper000`, `.paper001` -- the reproductions of papers 000 (WOCPF) and 001 (IFA-PF).

Experiments over the envs live in `agents.experiments` (they drive baseline policies).
"""
