"""lensmount.trace"""
