"""The daemon's service layer: the command protocol and its Unix-socket server, and systemd notification."""
