"""What Generate and Bake make in the scene: the marks on what the extension created, lens
lights, profile node trees and shadow masks, caustic layers and baked layers, Cycles'
caustics switches, and cleanup (Clear).

May import core, blender.read and blender.ui.properties; never commands.
"""
