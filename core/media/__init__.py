"""Participating media (docs/volumes.md): the Henyey-Greenstein phase function
(``phase.py``), homogeneous transmittance and free-flight sampling (``free_flight.py``),
delta and ratio tracking through a varying density (``tracking.py``), equiangular sampling
towards a point light (``equiangular.py``) and single scattering under a point light
(``single_scatter.py``). Units: metres, coefficients in 1/m. The beam radiance estimate over
the volume photon map is photons/beam.py (it needs the photon kd-tree, ranked above)."""
