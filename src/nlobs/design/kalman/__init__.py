"""The Kalman family and the particle filter: EKF, UKF, their square-root and iterated forms, and the bootstrap and
auxiliary particle filters, each continuous-discrete and on discrete-time maps; and the observers with a Riccati
differential equation (Kalman-Bucy, Kalman-like, LTV-based high-gain Kalman).

- ``_ekf``, ``_ukf``, ``_srukf``, ``_srekf``, ``_iekf``, ``_pf``: one kind each (``@kind``), continuous-discrete, and
  the entry point of the map variant when the model is discrete-time;
- ``_maps``: the map variants of the Gaussian filters (predict with u[k−1] from x̂[k−1|k−1], correct with y[k], Q per
  step);
- ``_riccati``: Kalman-Bucy, the Kalman-like observer for state-affine systems and the LTV-based high-gain Kalman
  observer (one kind each), and ``state_affine_parts``, which GPEBO and the augmented observer read too;
- ``_sqrt``: the square-root building blocks (QR triangularisation, triangular solves).

The kinds are registered by ``nlobs.design`` importing these modules in the order of ``nlobs kinds``; the public names
are ``nlobs.design.design_<kind>`` (and ``nlobs.design_<kind>``).
"""
