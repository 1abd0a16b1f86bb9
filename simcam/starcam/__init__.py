"""The star camera of seed 000 (and the optics, detector and spectra other instruments reuse): scenario, optics, detector, mosaic geometry, targets, rendering."""
