"""A small camera (two 256 x 256 chips, short plans) for tests that run many scenarios
(sweeps): every point of those tests varies this base. Imported by the sweep tests. Its
pixel maps are the scenario seed's for every trial (``new_maps_per_trial = false``), so that
its TE and HSFE truths are the run's, which a truth-mode sweep computes; the maps drawn per
trial (the default) are tested where a test sets them."""

import textwrap

TINY = textwrap.dedent("""
    [detector]
    chip_cols = 256
    chip_rows = 256
    gap_px = 10.0
    [lab]
    target_center_px = [-133.0, 0.0]
    [lab.target]
    spacing_mm = 0.5
    [optics]
    r_norm_px = 256.0
    [protocols.te]
    frames = 10
    [protocols.hsfe]
    conditions = 6
    frames = 6
    [protocols.chromatic]
    frames = 4
    field_centers_px = [[-150.0, -60.0], [150.0, -60.0], [-150.0, 60.0], [150.0, 60.0]]
    [protocols.distortion]
    frames = 4
    [render]
    stamp_px = 16
    wavelength_step_nm = 25.0
    [validation]
    new_maps_per_trial = false
    te_truth_frames = 60
    hsfe_truth_frames = 40
    hsfe_phase_grid = 2
    field_grid = 3
    batch_trials = 4
""")
