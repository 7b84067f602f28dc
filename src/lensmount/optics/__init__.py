"""lensmount.optics"""
