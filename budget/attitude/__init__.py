"""The attitude of a star camera from its star centroids (issue #34): weighted least squares on
the sphere (:mod:`budget.attitude.solve`) and the simulated camera on the real sky feeding it
(:mod:`budget.attitude.chain`). Docs: docs/attitude.md."""
