"""lensmount.integrators"""
