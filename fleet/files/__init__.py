"""Files on disk with their I/O: targets files (`targets_io`, over the pure codec in
`fleet.mission.targets_file`) and the secure profile's identities (`certs`)."""
