"""lensmount.analysis"""
