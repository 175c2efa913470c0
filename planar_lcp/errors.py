"""The errors a simulation raises, in a module of their own: the simulator (`planar_lcp.sim`, which exports them)
and the derivatives' runs (`planar_lcp.derivatives`) raise the same classes without importing each other."""


class SimulationError(RuntimeError):
    """A step failed (LCP not solved, or a non-finite state); the message names the step, the time and the cause."""


class NoRigidSolution(SimulationError):
    """A step failed because its contact problem has no solution, certified (a jam: `infeasibility`); `diagnosis`
    holds the certificate's StepDiagnosis."""

    def __init__(self, message, diagnosis):
        super().__init__(message)
        self.diagnosis = diagnosis
