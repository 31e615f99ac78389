"""The programs: each a thin root over the commands of the packages below it.

`fleet` (`fleet_cli`) and `fleet demo` (`demo`, which starts a fleet and drives it as
the ground does) sit above both `ground` and `onboard`: a root only parses its command
line, opens the bus once and runs a command on it (`fleet.transport.command`).
"""
