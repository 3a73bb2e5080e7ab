"""A DC motor as a co-simulation FMU (built with pythonfmu): armature voltage in, shaft
speed in, torque and current out. Electrical state: L·di/dt = V − R·i − k·ω; torque k·i.
With ω held over a communication step the current has an exact solution, so the step is
exact for held inputs."""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class DcMotor(Fmi2Slave):
    author = "cyclic-mechanism example"
    description = "DC motor: armature circuit with back-EMF, torque constant k"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.R = 0.5  # armature resistance (Ohm)
        self.L = 0.01  # armature inductance (H)
        self.k = 2.0  # torque constant (N.m/A) = back-EMF constant (V.s/rad)
        self.voltage = 24.0  # armature voltage (V)
        self.omega = 0.0  # shaft speed (rad/s), from the mechanism
        self.current = 0.0  # armature current (A)
        self.torque = 0.0  # shaft torque (N.m), to the mechanism
        parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        self.register_variable(Real("R", **parameter))
        self.register_variable(Real("L", **parameter))
        self.register_variable(Real("k", **parameter))
        self.register_variable(Real("voltage", causality=Fmi2Causality.input))
        self.register_variable(Real("omega", causality=Fmi2Causality.input))
        self.register_variable(Real("current", causality=Fmi2Causality.output))
        self.register_variable(Real("torque", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        steady = (self.voltage - self.k * self.omega) / self.R
        decay = math.exp(-step_size * self.R / self.L)
        self.current = steady + (self.current - steady) * decay
        self.torque = self.k * self.current
        return True
