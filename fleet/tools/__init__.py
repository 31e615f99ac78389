"""Stand-alone `fleet` subcommands over the layers below: `fleet decode` (a captured
serial stream, `decode_command`) and `fleet certs` (`certs_command`)."""
