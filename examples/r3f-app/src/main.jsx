// React Three Fiber: the character is a three.js object like any other — a <primitive> in the
// scene, stepped in useFrame. Clicking the floor walks there.
import { Canvas, useFrame } from '@react-three/fiber';
import { Character } from 'mm-avatar';
import { useEffect, useState } from 'react';
import { createRoot } from 'react-dom/client';

/** Loads a character (the shipped database and avatar) and frees it on unmount. */
function useCharacter() {
  const [character, setCharacter] = useState(null);
  useEffect(() => {
    let made = null;
    let gone = false;
    Character.create().then((c) => {
      if (gone) c.dispose();
      else {
        made = c;
        window.character = c; // for the console (and the tests): character.walkTo(3, 2)
        setCharacter(c);
      }
    }, (e) => console.warn(`mm-avatar: ${e.message}`));
    return () => {
      gone = true;
      made?.dispose();
    };
  }, []);
  return character;
}

function Walker({ character }) {
  useFrame(({ camera }, dt) => {
    character.update(Math.min(dt, 0.1));
    camera.lookAt(character.root.x, 1, character.root.z);
  });
  return <primitive object={character.object3d} />;
}

function App() {
  const character = useCharacter();
  return (
    <Canvas camera={{ position: [2.5, 1.8, 5], fov: 45 }}>
      <color attach="background" args={['#1d2126']} />
      <hemisphereLight args={['#ffffff', '#445566', 2.5]} />
      <directionalLight position={[3, 6, 4]} intensity={2} />
      <gridHelper args={[20, 20, '#556070', '#333a44']} />
      <mesh rotation-x={-Math.PI / 2} onClick={(e) => character?.walkTo(e.point.x, e.point.z)}>
        <planeGeometry args={[20, 20]} />
        <meshBasicMaterial transparent opacity={0} depthWrite={false} />
      </mesh>
      {character && <Walker character={character} />}
    </Canvas>
  );
}

createRoot(document.getElementById('root')).render(<App />);
