V 200 200      /* viewport (image) size in pixels: width height */
C 15 15 15     /* camera position */
A 6 6 6        /* target point the camera looks at */
U 0 1 0        /* camera up vector */
B 20 20        /* camera opening angles in degrees: horizontal vertical */
L 1            /* number of lights; then per light: */
C 1 1 1        /*   light colour r g b */
P 15 15 15     /*   light position */
I 1            /*   brightness */
O 1            /* number of objects; then per object: */
T 0            /*   object type: 0 sphere, 1 polyhedron */
C 3 7 1        /*   sphere centre */
R 2            /*   sphere radius */
S              /*   surface definition follows */
#C 1 0 0       /*   surface colour r g b */
#A 0.1         /*   ka  ambient coefficient */
#D 0.5         /*   kd  diffuse coefficient */
#S 0.4         /*   ks  specular (and global reflection) coefficient */
#T 0           /*   kt  transmission coefficient (0 = opaque) */
#E 6           /*   Phong exponent */
#N 1           /*   index of refraction */
