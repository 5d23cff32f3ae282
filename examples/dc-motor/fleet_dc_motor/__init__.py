"""A fleet of DC motors in a speed loop, as a unit type for fleetrl (``--env fleet_dc_motor.units:factory``).

:mod:`fleet_dc_motor.motor` is the physics of one unit (per-unit constants from the fleet seed);
:mod:`fleet_dc_motor.units` is the Gymnasium env that sets the task and judges it, and the factory.
"""
