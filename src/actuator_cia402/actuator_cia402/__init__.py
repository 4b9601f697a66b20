"""CiA 402 (CANopen drive profile) hardware driver for the joint actuator, and a simulated drive."""
