"""dancekit.motion"""
