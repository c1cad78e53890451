"""Read-only analysis of the results store: the paper's Table 6/7 layouts, figures and one
report.html (`report`, `surrogate_figure`). Nothing here runs a simulation or writes a row;
`coadapt_core.experiments` does."""
