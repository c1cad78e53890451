"""`coadapt dashboard`: a live, read-only web view of the results store and the run folders
(runs, a run, a grid, a comparison), served by the standard library's HTTP server with its
own page scripts and charting library shipped in `static/` (no internet needed).

Its parts: the store opened read-only in `readonly`, the pages' numbers in `runs_data`,
`run_data` and `grid_data` (computed by `coadapt_core.analysis`, never a second time), the
files of run folders in `files`, the HTTP server in `server`."""
