"""What knows nothing of PCHC: atomic file writes (``files``), finding NaN and inf (``finite``), the torchrun world and
process group (``distributed``), whether a window can open (``display``), counting a tensor's reads on the host
(``host_reads``), the error of a physics whose buffers overflowed (``physics_overflow``). Import each module by its
path; this package imports nothing."""
