"""dancekit.render"""
