"""lensmount.optics.io"""
