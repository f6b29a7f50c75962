"""The controller: constraint rows and projection (eq. 5), CLIK (eq. 27), the controller
interface, the force-loop bound, the supervisor and the laws (``laws/``)."""
