"""Experiments that run simulations and write their rows into the results store: ablation
grids (`grid`), cost landscapes (`landscape`) and sim-to-sim transfer (`transfer`).

Reports (`coadapt_core.analysis`) only read what these write."""
