"""What every experiment shares, and the experiments that need nothing above :mod:`filters`.

* :mod:`.runner` -- seeded jobs run sequentially, in a process pool or on Ray (same results).
* :mod:`.stats` -- confidence intervals from :mod:`scipy.stats` (Wilson, Student-t, normal, paired bootstrap).
* :mod:`.report` -- Markdown tables, number formats, generated blocks in documents, figure files.
* :mod:`.cli` -- typed command lines from frozen dataclasses (tyro), with the runner's options.
* :mod:`.paper000`, :mod:`.paper001` -- the reproductions of papers 000 (WOCPF) and 001 (IFA-PF).

Experiments over the envs live in :mod:`agents.experiments` (they drive baseline policies).
"""
