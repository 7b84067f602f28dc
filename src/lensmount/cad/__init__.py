"""lensmount.cad"""
