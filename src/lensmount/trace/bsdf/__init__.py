"""lensmount.trace.bsdf"""
