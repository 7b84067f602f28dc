"""lensmount.scene"""
