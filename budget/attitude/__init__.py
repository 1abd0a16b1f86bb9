"""The attitude of a star camera from its star centroids (issue #34): weighted least squares on
the sphere (:mod:`budget.attitude.solve`), the simulated camera on the real sky feeding it
(:mod:`budget.attitude.chain`), the lab's predictions of its error
(:mod:`budget.attitude.predict`), the study that judges them over the sky
(:mod:`budget.attitude.study`, its report :mod:`budget.attitude.report`) and the solve of a
sky frame (:mod:`budget.attitude.frame_solve`, ``budget attitude solve``). Docs: docs/attitude.md."""
