"""Drop-in interfaces of other shape-correspondence libraries on funcorr (``funcorr.compat.pyfm``)."""
