"""Design folder loading: lens, mount and scene files to validated inputs."""
