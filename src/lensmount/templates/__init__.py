"""lensmount.templates"""
