"""Test rigs that ship with robointel: a FANUC controller emulator on loopback and a host-stall probe.

- :mod:`robointel.testing.emulator` -- airo-fanuc's ``FakeCRXController`` in its own process on 127.0.0.1.
- :mod:`robointel.testing.host_probe` -- what the host did (load, steal, stalls) while a stream ran.
"""
