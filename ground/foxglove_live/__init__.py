"""`fleet foxglove`: the live fleet on a Foxglove WebSocket server (docs/foxglove.md).

`map_layers` turns what the fleet publishes into what Foxglove's Map panel draws (pure),
`bridge` carries the bus onto the server's channels, `command` is the subcommand.
"""
